"""Issue 15's acceptance on RENDERED twins: the hp3-paper rig, 5 calibration poses,
noise 1 gray level, PSF 0.7 px, one seed after another (poses, noise and the artefacts'
positions change with the seed).

For each seed: render (the ball scan and, with ``--verify``, the ball bar in 7 positions
and the plate in 3), calibrate (one-stage), measure the ball with its GUM budget
(``measure_sphere``: stripe-bias correction, calibration part, random part), and the ball
bar of position 1 (``measure_ball_bar``); compare with truth.json (the script reads the
truth; ``stripecal verify`` never does).

Reported per quantity (diameter, centre x/y/z, bar length): the error on every seed, the
expanded uncertainty U (k = 2), how many seeds have |error| <= U, the RMS of the errors
over the seeds and the ratio mean(U) / RMS (item 1: <= 3, i.e. not inflated); pooled
coverage over quantities and seeds (DECISIONS 7: >= 90 of 100); the largest |error| per
quantity (item 2: diameter 0.002, centre 0.005, bar 0.005 mm); the mean of each standard part
of the budget (random, calibration, robot, systematic). ``--json`` keeps per seed and
quantity [error, U, random, calibration, robot, systematic] in mm.

Usage: python scripts/measurement_acceptance.py [--seeds 20] [--first 1] [--verify]
[--out DIR] [--json OUT.json]   (about 30 s per seed on two cores, 60 s with --verify).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Dict, List

import numpy as np

import stripecal
from stripecal import sim

LIMITS = {"diameter": 0.002, "centre x": 0.005, "centre y": 0.005, "centre z": 0.005, "bar length": 0.005}


def parts(budget: Dict[str, float]) -> List[float]:
    """U (k = 2), then the standard uncertainties random, calibration, robot, systematic."""
    return [float(budget[k]) for k in ("expanded_mm", "random_mm", "calibration_mm", "robot_mm", "systematic_mm")]


def one_seed(seed: int, root: Path, with_verify: bool) -> Dict[str, List[float]]:
    knobs = {"seed": seed, "poses": {"count": 5}, "imaging": {"noise_gray": 1.0, "psf_sigma_px": 0.7}}
    if with_verify:
        # Position 1 of the ball bar only (the others are verify's; no plate).
        knobs["verify"] = {"enabled": True, "bar_positions": 1, "plate_positions": 0}
    cfg = sim.preset("hp3-paper", **knobs)
    summary = sim.Twin(cfg).write(root)
    cal = stripecal.calibrate(summary["calib_dir"])
    scan = summary["scan_dir"]
    assert scan is not None
    truth = stripecal.load_truth(Path(scan) / "truth.json")
    sphere = truth.sphere
    assert sphere is not None
    d0 = float(sphere["diameter_mm"])
    c0 = np.asarray(sphere["center_mm"], np.float64)
    m = stripecal.measure_sphere(cal, scan, diameter_range_mm=(0.8 * d0, 1.2 * d0))
    u = m["uncertainty"]
    out: Dict[str, List[float]] = {"diameter": [m["diameter_mm"] - d0, *parts(u["diameter"])]}
    for k, a in enumerate("xyz"):
        out[f"centre {a}"] = [m["center_mm"][k] - c0[k], *parts(u["center"][k])]
    verify_dir = summary.get("verify_dir") if with_verify else None
    if verify_dir:
        bar_dir = Path(str(verify_dir)) / "bar_1"
        bt = json.loads((bar_dir / "truth.json").read_text())
        centres = [np.asarray(s["center_mm"], np.float64) for s in bt["spheres"]]
        diam = [float(s["diameter_mm"]) for s in bt["spheres"]]
        b = stripecal.measure_ball_bar(cal, bar_dir, diameter_range_mm=(0.8 * min(diam), 1.2 * max(diam)))
        length = float(np.linalg.norm(centres[0] - centres[1]))
        out["bar length"] = [b["distance"]["value_mm"] - length, *parts(b["distance"])]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--verify", action="store_true", help="also the ball bar (renders the verify artefacts)")
    ap.add_argument("--out", help="keep the renders here (default: a temporary folder)")
    ap.add_argument("--json", help="write the per-seed numbers")
    a = ap.parse_args()
    results: Dict[int, Dict[str, List[float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(a.out or tmp)
        for seed in range(a.first, a.first + a.seeds):
            r = one_seed(seed, base / f"seed{seed}", a.verify)
            results[seed] = r
            print(f"seed {seed:3d}: " + "  ".join(f"{k} {v[0]:+.5f} (U {v[1]:.5f})" for k, v in r.items()), flush=True)
    quantities = [k for k in LIMITS if all(k in r for r in results.values())]
    inside = total = 0
    print(f"\n{'quantity':<11} {'inside U':>9} {'RMS err':>9} {'mean U':>9} {'U/RMS':>6} {'max |err|':>10} {'limit':>7}")
    for q in quantities:
        e = np.array([results[s][q][0] for s in results])
        u = np.array([results[s][q][1] for s in results])
        n_in = int(np.sum(np.abs(e) <= u))
        inside += n_in
        total += len(e)
        rms = float(np.sqrt(np.mean(e**2)))
        print(f"{q:<11} {n_in:>5}/{len(e):<3} {rms:9.5f} {u.mean():9.5f} {u.mean() / rms:6.2f} "
              f"{np.abs(e).max():10.5f} {LIMITS[q]:7.3f}")
    print(f"\npooled coverage: {inside} of {total} inside U (k = 2)")
    print(f"\n{'mean parts':<11} {'random':>9} {'calib':>9} {'robot':>9} {'system':>9}   (standard, mm)")
    for q in quantities:
        p = np.array([results[s][q][2:6] for s in results]).mean(axis=0)
        print(f"{q:<11} " + " ".join(f"{x:9.5f}" for x in p))
    if a.json:
        Path(a.json).write_text(json.dumps({str(k): v for k, v in results.items()}, indent=1))


if __name__ == "__main__":
    main()
