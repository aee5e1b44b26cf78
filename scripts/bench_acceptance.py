"""Issue 17, acceptance item 1: bench calibration on the twin, 15 views, noise 1, PSF 0.7.

Until the twin has its own bench mode, a bench dataset is the robot twin's calibration
dataset with the pose columns removed from views.csv (header `board_image,laser_image`):
the images are the same, the board poses are then free. For every seed the script prints
the errors against truth.json (fu in %, u0 and v0 in px, the plane's offset d in mm and
its normal's angle in deg), the targets (fu 0.01 %, u0 and v0 0.1 px, plane 0.01 mm), and
how many of the estimated numbers (camera fu fv u0 v0 k1, plane normal[0..2] and d) the
reported 3-sigma covers; then the totals.

    python scripts/bench_acceptance.py [--seeds 1-10] [--work DIR] [--robot] [--twin-bench]

`--twin-bench`: the twin's own bench mode instead (`bench.enabled`: 15 hand-placed board
poses, tilts up to 45 deg, 3 of them partly out of the image; docs/twin.md).

`--robot` also calibrates the same views with their robot poses (for comparison).
`--prior` (issue 17, item 3): the bench calibration as the prior (the default `--from`:
camera and plane with their covariance propagated), held (`--fix camera,laser_plane`),
for 3 robot views of the same twin (views 0, 5, 10): the hand-eye error against the
truth (targets 0.005 deg, 0.02 mm), its sigma, and the same 3 views without the bench.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import time
from typing import Dict, List, Tuple

import stripecal as sc
from stripecal import sim


def render(seed: int, work: str) -> str:
    """The twin's calibration dataset of `seed` (rendered once), as a bench dataset."""
    root = os.path.join(work, f"s{seed}")
    if not os.path.exists(os.path.join(root, "calib", "truth.json")):
        cfg = sim.preset(
            "hp3-paper",
            seed=seed,
            poses={"count": 15},
            imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
        )
        sim.Twin(cfg).write(root)
    return os.path.join(root, "calib")


def render_bench(seed: int, work: str) -> str:
    """The twin's bench mode dataset of `seed` (rendered once)."""
    root = os.path.join(work, f"b{seed}")
    if not os.path.exists(os.path.join(root, "calib", "truth.json")):
        cfg = sim.preset(
            "hp3-paper",
            seed=seed,
            imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
            bench={"enabled": True},
        )
        sim.Twin(cfg).write(root)
    return os.path.join(root, "calib")


def to_bench(src: str, dst: str) -> str:
    """A copy of dataset `src`'s views.csv without pose columns in `dst` (images and
    rig.json linked)."""
    os.makedirs(dst, exist_ok=True)
    for name in ("images", "rig.json", "truth.json"):
        link = os.path.join(dst, name)
        if not os.path.exists(link):
            os.symlink(os.path.join(os.path.abspath(src), name), link)
    with open(os.path.join(src, "views.csv"), newline="") as f:
        rows = list(csv.reader(f))
    with open(os.path.join(dst, "views.csv"), "w") as f:
        f.write("board_image,laser_image\n")
        for r in rows[1:]:
            f.write(f"{r[0]},{r[1]}\n")
    return dst


def figures(cal: sc.Calibration, truth: Dict) -> Tuple[Dict[str, float], List[Tuple[str, float, float]]]:
    """The errors against the truth, and (name, error, sigma) of every estimated number."""
    cam, tc = cal.camera, truth["camera"]
    plane = cal.laser_plane
    assert plane is not None
    n, d = plane
    tn, td = truth["laser_plane"]["normal"], truth["laser_plane"]["d_mm"]
    u = cal.uncertainty
    uc, up = u["camera"], u["laser_plane"]
    dot = max(-1.0, min(1.0, sum(a * b for a, b in zip(n, tn))))
    errs = {
        "fu_pct": 100.0 * (cam.fu - tc["fu"]) / tc["fu"],
        "u0_px": cam.u0 - tc["u0"],
        "v0_px": cam.v0 - tc["v0"],
        "d_mm": d - td,
        "normal_deg": math.degrees(math.acos(dot)),
    }
    nums = [
        ("fu", cam.fu - tc["fu"], uc["fu"]),
        ("fv", cam.fv - tc["fv"], uc["fv"]),
        ("u0", cam.u0 - tc["u0"], uc["u0"]),
        ("v0", cam.v0 - tc["v0"], uc["v0"]),
        ("k1", cam.distortion[0] - tc["distortion"][0], uc["distortion"][0]),
    ]
    nums += [(f"n{k}", n[k] - tn[k], up["normal"][k]) for k in range(3)]
    nums.append(("d", d - td, up["d_mm"]))
    return errs, nums


def _rotvec_matrix(w: List[float]) -> List[List[float]]:
    th = math.sqrt(sum(x * x for x in w))
    if th < 1e-15:
        return [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    k = [x / th for x in w]
    kx = [[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]]
    kk = [[sum(kx[i][m] * kx[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
    return [[(1.0 if i == j else 0.0) + math.sin(th) * kx[i][j] + (1 - math.cos(th)) * kk[i][j]
             for j in range(3)] for i in range(3)]


def prior_figures(bench: sc.Calibration, src: str, truth: Dict, work: str) -> None:
    """Item 3: 3 robot views with the bench held, and without it."""
    three = os.path.join(work, "three")
    os.makedirs(three, exist_ok=True)
    for name in ("images", "rig.json"):
        link = os.path.join(three, name)
        if not os.path.exists(link):
            os.symlink(os.path.join(os.path.abspath(src), name), link)
    with open(os.path.join(src, "views.csv")) as f:
        lines = f.read().splitlines()
    with open(os.path.join(three, "views.csv"), "w") as f:
        f.write("\n".join([lines[0], lines[1], lines[6], lines[11]]) + "\n")
    bench_json = os.path.join(work, "bench.json")
    bench.save(bench_json)
    x = _rotvec_matrix(truth["hand_cam"]["rotation_vector"])
    xt = truth["hand_cam"]["translation_mm"]
    for label, kw in (("prior", {"from_calibration": bench_json}),
                      ("held", {"from_calibration": bench_json, "fix": ["camera", "laser_plane"]}),
                      ("alone", {})):
        try:
            c = sc.calibrate(three, leave_one_out=False, accept_poor=True, **kw)  # type: ignore[arg-type]
        except sc.StripecalError as e:
            print(f"     3 views {label}: {e}")
            continue
        h = c.hand_cam
        tr = sum(h[m][i] * x[m][i] for i in range(3) for m in range(3))
        ang = math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1) / 2))))
        dt = math.sqrt(sum((h[i][3] - xt[i]) ** 2 for i in range(3)))
        hs = c.uncertainty.get("hand_cam", {})
        rs = max(hs.get("rotation_vector", [float("nan")]))
        ts = max(hs.get("translation_mm", [float("nan")]))
        cs = c.uncertainty["camera"]["fu"]
        print(f"     3 views {label:>10}: hand-eye error {ang:.5f} deg {dt:.4f} mm; sigma (largest) "
              f"{math.degrees(rs):.5f} deg {ts:.4f} mm; fu sigma {cs:.4f} (bench {bench.uncertainty['camera']['fu']:.4f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="1-10")
    ap.add_argument("--work", default="/tmp/stripecal_bench_acceptance")
    ap.add_argument("--robot", action="store_true")
    ap.add_argument("--prior", action="store_true")
    ap.add_argument("--twin-bench", action="store_true")
    a = ap.parse_args()
    if a.twin_bench and (a.robot or a.prior):
        ap.error("--twin-bench has no robot poses: not with --robot or --prior")
    lo, _, hi = a.seeds.partition("-")
    seeds = list(range(int(lo), int(hi or lo) + 1))
    targets = {"fu_pct": 0.01, "u0_px": 0.1, "v0_px": 0.1, "d_mm": 0.01}
    covered = total = 0
    all_ok = True
    print(
        f"{'seed':>4} {'fu %':>9} {'u0 px':>8} {'v0 px':>8} {'d mm':>9} {'n deg':>8} "
        f"{'3s cover':>8} {'LOO mm':>7} {'t s':>5}  worst |err|/sigma"
    )
    for seed in seeds:
        if a.twin_bench:
            src = bench = render_bench(seed, a.work)
        else:
            src = render(seed, a.work)
            bench = to_bench(src, os.path.join(a.work, f"s{seed}", "bench"))
        with open(os.path.join(src, "truth.json")) as f:
            truth = json.load(f)
        t0 = time.perf_counter()
        cal = sc.calibrate(bench)
        dt = time.perf_counter() - t0
        errs, nums = figures(cal, truth)
        ok = all(abs(errs[k]) <= v for k, v in targets.items())
        all_ok &= ok
        cov = sum(abs(e) <= 3 * s for _, e, s in nums)
        covered += cov
        total += len(nums)
        worst = max(nums, key=lambda x: abs(x[1]) / x[2])
        loo = cal.leave_one_out
        loo_mm = loo["median_stripe_rms_mm"] if loo else None
        loo_mm = float("nan") if loo_mm is None else loo_mm
        print(
            f"{seed:>4} {errs['fu_pct']:>9.5f} {errs['u0_px']:>8.4f} {errs['v0_px']:>8.4f} "
            f"{errs['d_mm']:>9.5f} {errs['normal_deg']:>8.5f} {cov:>5}/{len(nums)} "
            f"{loo_mm:>7.4f} {dt:>5.2f}  {worst[0]} {abs(worst[1]) / worst[2]:.2f}"
            + ("" if ok else "  MISSES A TARGET")
        )
        if a.robot:
            rc = sc.calibrate(src)
            re, rn = figures(rc, truth)
            rcov = sum(abs(e) <= 3 * s for _, e, s in rn)
            print(
                f"{'rob':>4} {re['fu_pct']:>9.5f} {re['u0_px']:>8.4f} {re['v0_px']:>8.4f} "
                f"{re['d_mm']:>9.5f} {re['normal_deg']:>8.5f} {rcov:>5}/{len(rn)}"
            )
        if a.prior:
            prior_figures(cal, src, truth, os.path.join(a.work, f"s{seed}"))
    print(
        f"targets on every seed: {'yes' if all_ok else 'NO'}; 3-sigma covers the truth on "
        f"{covered}/{total} = {100.0 * covered / max(total, 1):.1f} % of the estimated numbers "
        f"(acceptance: at least 95 %)"
    )


if __name__ == "__main__":
    main()
