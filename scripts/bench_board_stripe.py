"""What the board's stripe-bias correction costs (pipeline/calibrate/board_stripe/): the twin's
calibration folder (hp3-paper, noise 1, PSF 0.7, N poses), `stripecal.calibrate` with
`board_stripe_bias=True` (default) and False, alternating, median of R runs each.

Usage: python scripts/bench_board_stripe.py [--poses 5 15] [--runs 5]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import stripecal
from stripecal import sim


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, nargs="+", default=[5, 15])
    ap.add_argument("--runs", type=int, default=5)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for n in a.poses:
            cfg = sim.preset("hp3-paper", seed=1, poses={"count": n}, imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7})
            summary = sim.Twin(cfg).write(Path(tmp) / f"p{n}")
            calib = summary["calib_dir"]
            times = {True: [], False: []}
            for _ in range(a.runs):
                for on in (False, True):
                    t = time.perf_counter()
                    stripecal.calibrate(calib, board_stripe_bias=on)
                    times[on].append(time.perf_counter() - t)
            off, on = statistics.median(times[False]), statistics.median(times[True])
            print(f"{n:3d} views: without {off * 1e3:7.1f} ms   with {on * 1e3:7.1f} ms   ratio {on / off:.2f}")


if __name__ == "__main__":
    main()
