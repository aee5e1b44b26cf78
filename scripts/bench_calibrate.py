"""Issue 41, acceptance item 1: `stripecal calibrate` of the 15-view hp3-paper twin (noise 1
gray level), whole process, default options, against an OpenCV multi-stage pipeline on the
same images (BENCHMARKS.md, "Calibration time against OpenCV (issue 41)").

    python scripts/bench_calibrate.py [--views 15] [--repeat 5] [--work DIR]

Both are timed as whole processes (interpreter start, imports, PNG decoding, everything
up to the written result), interleaved, best of `--repeat`; CPU time (user + system of
the child) beside the wall time:

- stripecal: `python -m stripecal.cli calibrate DATASET -o OUT` (the `stripecal` console
  script), default options: leave-one-view-out, the board's stripe-bias correction and the
  robot-pose noise model all produced;
- the peer (`--peer`, this file run as a child): per view cv2.imread of the board and the
  laser image; cv2.findCirclesGrid(board, (cols, rows), CALIB_CB_SYMMETRIC_GRID) with its
  default blob detector (the board's dark circles); cv2.calibrateCamera (k1 only, as
  the rig's radial1 model); cv2.solvePnP per view; the robot poses by the DH chain of
  rig.json from the joint readings; cv2.calibrateHandEye (PARK); the laser line per
  scan line (argmax and a 3-point centroid on the laser image),
  back-projected onto each view's board plane, and the plane through all of them by SVD.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from typing import List, Tuple


def peer(dataset: str, out: str) -> None:
    """The OpenCV multi-stage pipeline (module docs); writes its result to `out`."""
    import csv

    import cv2
    import numpy as np

    rig = json.load(open(os.path.join(dataset, "rig.json")))
    b = rig["board"]
    rows, cols, pitch = int(b["rows"]), int(b["cols"]), float(b["pitch_mm"])
    size = (int(rig["camera"]["width"]), int(rig["camera"]["height"]))
    obj = np.zeros((rows * cols, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * pitch

    def dh(q_deg: List[float]) -> np.ndarray:
        t = np.eye(4)
        for j, q in zip(rig["robot"]["joints"], q_deg):
            th = np.radians(q - j["theta0_deg"])
            al = np.radians(j["alpha_deg"])
            ct, st, ca, sa = np.cos(th), np.sin(th), np.cos(al), np.sin(al)
            a = np.array(
                [
                    [ct, -st * ca, st * sa, j["a_mm"] * ct],
                    [st, ct * ca, -ct * sa, j["a_mm"] * st],
                    [0, sa, ca, j["d_mm"]],
                    [0, 0, 0, 1],
                ]
            )
            t = t @ a
        return t

    views = []
    with open(os.path.join(dataset, "views.csv"), newline="") as f:
        for row in csv.DictReader(f):
            q = [float(row[k]) for k in sorted(row) if k.startswith("q")]
            board = cv2.imread(os.path.join(dataset, row["board_image"]), cv2.IMREAD_GRAYSCALE)
            laser = cv2.imread(os.path.join(dataset, row["laser_image"]), cv2.IMREAD_GRAYSCALE)
            ok, centres = cv2.findCirclesGrid(board, (cols, rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
            if ok:
                views.append((dh(q), board, laser, centres))
    img_pts = [v[3] for v in views]
    flags = cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    rms, k, dist, _, _ = cv2.calibrateCamera([obj] * len(views), img_pts, size, None, None, flags=flags)
    r_g2b, t_g2b, r_t2c, t_t2c, planes, pts = [], [], [], [], [], []
    for a, board, laser, centres in views:
        ok, rvec, tvec = cv2.solvePnP(obj, centres, k, dist)
        r = cv2.Rodrigues(rvec)[0]
        r_g2b.append(a[:3, :3])
        t_g2b.append(a[:3, 3])
        r_t2c.append(r)
        t_t2c.append(tvec.ravel())
        # The laser line (the laser image: the sheet alone): a 3-point centroid per row.
        d = laser.astype(np.float32)
        i = np.argmax(d, axis=1)
        rows_ok = (d[np.arange(d.shape[0]), i] > 50) & (i > 0) & (i < d.shape[1] - 1)
        y = np.nonzero(rows_ok)[0]
        x = i[rows_ok]
        l, c, rr = d[y, x - 1], d[y, x], d[y, x + 1]
        u = x + (rr - l) / np.maximum(l + c + rr, 1e-9)
        uv = np.stack([u, y], axis=1).astype(np.float64).reshape(-1, 1, 2)
        rays = cv2.undistortPoints(uv, k, dist).reshape(-1, 2)
        rays = np.hstack([rays, np.ones((len(rays), 1))])
        n = r[:, 2]
        s = (n @ tvec.ravel()) / (rays @ n)
        pts.append(rays * s[:, None])
    r_x, t_x = cv2.calibrateHandEye(r_g2b, t_g2b, r_t2c, t_t2c, method=cv2.CALIB_HAND_EYE_PARK)
    p = np.vstack(pts)
    c = p.mean(axis=0)
    # the thin SVD (full_matrices=True would form an n x n U: 1.2 s of 1.7 s for 15 views)
    normal = np.linalg.svd(p - c, full_matrices=False)[2][2]
    json.dump(
        {
            "views": len(views),
            "rms_px": rms,
            "fx": k[0, 0],
            "hand_cam_t": t_x.ravel().tolist(),
            "plane": {"normal": normal.tolist(), "d": float(normal @ c)},
        },
        open(out, "w"),
    )


def timed(cmd: List[str]) -> Tuple[float, float]:
    """Wall and CPU (user + system) seconds of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--views", type=int, default=15)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--work", default=None)
    ap.add_argument("--peer", nargs=2, metavar=("DATASET", "OUT"))
    a = ap.parse_args()
    if a.peer:
        peer(*a.peer)
        return
    import tempfile

    import stripecal
    import stripecal.sim

    work = a.work or tempfile.mkdtemp()
    calib = os.path.join(work, "calib")
    if not os.path.exists(os.path.join(calib, "truth.json")):
        cfg = stripecal.sim.preset(
            "hp3-paper",
            poses={"count": a.views},
            imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
            scan={"enabled": False},
        )
        stripecal.sim.Twin(cfg).write(work)
    py = sys.executable
    ours = [py, "-m", "stripecal.cli", "calibrate", calib, "-o", os.path.join(work, "calibration.json")]
    theirs = [py, os.path.abspath(__file__), "--peer", calib, os.path.join(work, "opencv.json")]
    best = {"stripecal": (1e9, 1e9), "opencv": (1e9, 1e9)}
    for _ in range(a.repeat):
        for name, cmd in (("stripecal", ours), ("opencv", theirs)):
            w, c = timed(cmd)
            best[name] = (min(best[name][0], w), min(best[name][1], c))
    (sw, sc), (ow, oc) = best["stripecal"], best["opencv"]
    print(f"{a.views} views, best of {a.repeat}, interleaved; load {os.getloadavg()[0]:.2f}")
    print(f"stripecal calibrate: wall {sw:.3f} s, cpu {sc:.3f} s")
    print(f"opencv pipeline:     wall {ow:.3f} s, cpu {oc:.3f} s")
    print(f"ratio stripecal / opencv: wall {sw / ow:.2f}, cpu {sc / oc:.2f}")
    print("opencv result:", open(os.path.join(work, "opencv.json")).read())


if __name__ == "__main__":
    main()
