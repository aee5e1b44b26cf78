"""The quality gates' false-alarm rate on the twin (issue 13, acceptance item 3).

Renders the paper's rig (hp3-paper: 5 calibration views) for SEEDS seeds at each read
noise, calibrates every dataset with the default options and counts the calibrations
the gates reject (a CalibrationQualityError) or that leave a view out. Every one of
them is a good calibration: a rejection is a false alarm.

    python scripts/gate_false_alarms.py [SEEDS] [NOISE ...]     (default 20 seeds, noise 1 and 4)
"""

from __future__ import annotations

import sys
import tempfile
import time

import stripecal
import stripecal.sim


def run(seeds: int, noises: list[float]) -> int:
    rejected = 0
    with tempfile.TemporaryDirectory() as tmp:
        for noise in noises:
            worst = 0.0
            left_out = 0
            t0 = time.monotonic()
            for seed in range(seeds):
                cfg = stripecal.sim.preset("hp3-paper", {"seed": seed, "imaging": {"noise_gray": noise},
                                                         "scan": {"enabled": False}})
                out = f"{tmp}/n{noise}_s{seed}"
                stripecal.sim.Twin(cfg).write(out)
                try:
                    cal = stripecal.calibrate(f"{out}/calib")
                except stripecal.CalibrationQualityError as e:
                    rejected += 1
                    print(f"noise {noise} seed {seed}: REJECTED: {e}")
                    continue
                checks = cal.quality["checks"]
                left_out += sum(1 for c in checks if c["views"])
                for c in checks:
                    if c["views"]:
                        print(f"noise {noise} seed {seed}: {c['name']} left out views {c['views']}: {c['message']}")
                worst = max(worst, cal.quality["circle_rms_px"])
            print(f"noise {noise}: {seeds} seeds in {time.monotonic() - t0:.0f} s, "
                  f"calibrations with views left out {left_out}, worst circle RMS {worst:.4f} px")
    total = seeds * len(noises)
    print(f"rejected {rejected} of {total} good calibrations")
    return rejected


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    levels = [float(x) for x in sys.argv[2:]] or [1.0, 4.0]
    sys.exit(1 if run(n, levels) else 0)
