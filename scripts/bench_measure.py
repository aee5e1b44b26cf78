"""Times `measure_sphere` with and without the curved-surface stripe-bias correction on
the hp3-paper ball scan (BENCHMARKS.md, "Measurement uncertainty").

Usage: python scripts/bench_measure.py [TWIN_DIR]   (renders the twin, seed 1, into a
temporary folder when none is given; best of 3 runs each, wall and the process's CPU
time, all threads)."""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import stripecal
from stripecal import sim


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tmp)
        if not (root / "scan").exists():
            sim.Twin(sim.preset("hp3-paper", seed=1)).write(root)
        cal = stripecal.calibrate(root / "calib")
        cloud = stripecal.reconstruct_scan(cal, root / "scan")
        for correct in (False, True):
            best, best_cpu = float("inf"), float("inf")
            for _ in range(3):
                t, c = time.perf_counter(), time.process_time()
                stripecal.measure_sphere(cal, root / "scan", cloud=cloud, diameter_range_mm=(36, 54),
                                         correct_bias=correct)
                best = min(best, time.perf_counter() - t)
                best_cpu = min(best_cpu, time.process_time() - c)
            print(f"measure_sphere correct_bias={correct}: {best:.3f} s, CPU {best_cpu:.3f} s "
                  f"({len(cloud)} points)")


if __name__ == "__main__":
    main()
