"""Issue 18, acceptance 5: a line profiler's calibration against
``scipy.optimize.least_squares`` on the same problem, timed in ONE process on one core.

The problem: the ``hp3-profiler`` twin, 15 profiles of ~2,500 points (``line_length_mm``
75: 2,500 samples at 0.03 mm, 2 % dropouts), sphere diameter declared.

- stripecal: ``stripecal.calibrate(path, leave_one_out=False)`` (``RAYON_NUM_THREADS=1``
  is set before stripecal is imported; numpy's BLAS threads are set to 1 too): reading the 15 profile files, the arcs, the
  consensus and closed-form start, the adjustment with its point re-selection, the mirror
  test (a second adjustment) and the gates. It is charged with more work than scipy.
- scipy: ``least_squares(fun, x0, jac="2-point", loss="soft_l1", f_scale=0.03)`` over
  ``T_hand_sensor`` (rotation vector + translation) and the sphere centre, residuals
  ``|A_i (R_X p + t_X) - c| - R`` over the arcs' points, from the same closed-form start:
  both from ``stripecal.profiler_start(path)`` (the pipeline's own first two steps; not
  timed). ``f_scale`` = 3 x the profile noise (0.01 mm). The residuals are vectorised per
  view (one 2x3 matmul per view, 15 views).

Reported: the median wall time of each over ``--repeat`` runs, the ratio, and both
results' hand-eye errors against the truth.

Usage: pip install -e '.[bench]'; python scripts/bench_profiler_scipy.py [--repeat 20]
[--work DIR]
"""

from __future__ import annotations

import os

os.environ["RAYON_NUM_THREADS"] = "1"  # before stripecal is imported: one core
for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"  # and numpy's BLAS on one core too

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, Callable, Dict, List, Tuple  # noqa: E402

import numpy as np  # noqa: E402
from scipy.optimize import least_squares  # noqa: E402

import stripecal  # noqa: E402
from stripecal import sim  # noqa: E402

NOISE_MM = 0.01


def residual_function(start: Dict[str, Any]) -> Tuple[Callable[[np.ndarray], np.ndarray], np.ndarray]:
    """The residuals and the start vector ``[rv_X, t_X, c]``."""
    ra = [np.asarray(a)[:3, :3] for a in start["flanges"]]
    ta = [np.asarray(a)[:3, 3] for a in start["flanges"]]
    pts = [np.ascontiguousarray(p) for p in start["points"]]  # (M_i, 2): x, z
    radius = 0.5 * float(start["diameter_mm"])
    m = sum(len(p) for p in pts)

    def fun(x: np.ndarray) -> np.ndarray:
        rx = stripecal.rotvec_to_matrix(x[:3])
        tx, c = x[3:6], x[6:9]
        out = np.empty(m)
        k = 0
        for r, t, p in zip(ra, ta, pts):
            rr = r @ rx  # R_A R_X
            # P = R_A (R_X p + t_X) + t_A with p = (x, 0, z): the columns x and z of R_A R_X
            pb = p @ rr[:, (0, 2)].T + (r @ tx + t - c)
            out[k : k + len(p)] = np.sqrt(np.einsum("ij,ij->i", pb, pb)) - radius
            k += len(p)
        return out

    h = np.asarray(start["hand_sensor"])
    x0 = np.concatenate([stripecal.matrix_to_rotvec(h[:3, :3]), h[:3, 3], np.asarray(start["centre_mm"])])
    return fun, x0


def hand_eye_error(h: np.ndarray, truth: Dict[str, Any]) -> Tuple[float, float]:
    t = np.eye(4)
    t[:3, :3] = stripecal.rotvec_to_matrix(np.asarray(truth["rotation_vector"], dtype=float))
    t[:3, 3] = truth["translation_mm"]
    e = np.linalg.inv(h) @ t
    return math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(e[:3, :3]) - 1) / 2)))), float(np.linalg.norm(e[:3, 3]))


def median_time(f: Callable[[], object], repeat: int) -> Tuple[float, List[float]]:
    f()  # warm-up
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), ts


def main() -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--work", help="where the twin is rendered (default: a temporary folder)")
    a = ap.parse_args()
    tmp = None if a.work else tempfile.TemporaryDirectory(prefix="bench_profiler_")
    root = Path(a.work or tmp.name)  # type: ignore[union-attr]
    cfg = sim.preset("hp3-profiler", seed=a.seed, profiler={"line_length_mm": 75.0, "views": 15, "scan_frames": 1})
    sim.Twin(cfg).write(root)
    calib = root / "calib"
    truth = sim.profiler_truth(calib)

    start = stripecal.profiler_start(calib)
    fun, x0 = residual_function(start)
    npts = sum(len(p) for p in start["points"])

    def run_read() -> int:
        d = stripecal.load_profile_dataset(calib)
        return sum(len(d.profile(i)) for i in range(len(d.profiles)))

    all_pts = run_read()

    def run_stripecal() -> stripecal.ProfilerCalibration:
        cal = stripecal.calibrate(calib, leave_one_out=False)
        assert isinstance(cal, stripecal.ProfilerCalibration)
        return cal

    def run_adjust() -> Any:
        return stripecal.profiler_adjust(start)

    def run_scipy() -> Any:
        return least_squares(fun, x0, jac="2-point", loss="soft_l1", f_scale=3.0 * NOISE_MM)

    t_sc, _ = median_time(run_stripecal, a.repeat)
    t_rd, _ = median_time(run_read, a.repeat)
    t_ad, _ = median_time(run_adjust, a.repeat)
    t_sp, _ = median_time(run_scipy, max(3, a.repeat // 4))
    cal = run_stripecal()
    adj = run_adjust()
    sol = run_scipy()
    hs = np.eye(4)
    hs[:3, :3] = stripecal.rotvec_to_matrix(sol.x[:3])
    hs[:3, 3] = sol.x[3:6]
    e_sc = hand_eye_error(np.asarray(cal.hand_sensor), truth["hand_cam"])
    e_sp = hand_eye_error(hs, truth["hand_cam"])
    e_ad = hand_eye_error(np.asarray(adj["hand_sensor"]), truth["hand_cam"])
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}; "
          f"python {platform.python_version()}, numpy {np.__version__}, "
          f"scipy {__import__('scipy').__version__}, stripecal {stripecal.__version__}")
    print(f"problem: {len(start['points'])} profiles, {all_pts} points ({all_pts / len(start['points']):.0f} per profile), "
          f"{npts} arc points in scipy's residuals, 9 parameters")
    print()
    print("| solver | median time ms | runs | rot err deg | trans err mm | evaluations |")
    print("|---|---:|---:|---:|---:|---:|")
    print(f"| stripecal.calibrate(path, leave_one_out=False), 1 thread | {1e3 * t_sc:.1f} | {a.repeat} | "
          f"{e_sc[0]:.5f} | {e_sc[1]:.5f} | - |")
    print(f"| stripecal.profiler_adjust(start): the adjustment alone, same points, same start | {1e3 * t_ad:.1f} | "
          f"{a.repeat} | {e_ad[0]:.5f} | {e_ad[1]:.5f} | {adj['iterations']} iterations |")
    print(f"| of which reading the 15 files (load_profile_dataset + profile(i)) | {1e3 * t_rd:.1f} | {a.repeat} | - | - | - |")
    print(f"| scipy least_squares 2-point, soft_l1 (f_scale 0.03 mm) | {1e3 * t_sp:.1f} | {max(3, a.repeat // 4)} | "
          f"{e_sp[0]:.5f} | {e_sp[1]:.5f} | {sol.nfev} (+ {9 * (sol.njev or 0)} for the Jacobian) |")
    print(f"\nthe same problem (the adjustment from the same start over the same points): "
          f"scipy / stripecal.profiler_adjust = {t_sp / t_ad:.1f}x")
    print(f"the whole calibration with its checks: scipy / stripecal.calibrate = {t_sp / t_sc:.1f}x; "
          f"without reading the files {t_sp / max(t_sc - t_rd, 1e-9):.1f}x")
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
