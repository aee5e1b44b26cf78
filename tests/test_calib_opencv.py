"""Issue 4, acceptance 4: the whole calibration against a multi-stage OpenCV pipeline on
the SAME rendered images, median over 10 seeds of the 15-pose hp3-paper twin
(``STRIPECAL_OPENCV_SEEDS=10``; by default the first 3 of them, which keeps CI's run
within its time: the 10 took about 80 s on 2 cores).

OpenCV: cv2.findCirclesGrid centres (assigned to board indices by the nearest of our
detected circles: OpenCV's own ordering is not what is measured here),
cv2.calibrateCamera with the matching distortion flags (radial1 = k1 only), the laser
plane fitted to the same stripe points back-projected with OpenCV's camera and
extrinsics, cv2.calibrateRobotWorldHandEye (LI and SHAH) on the same robot poses.
Ours: stripecal.calibrate (one-stage). Errors against truth.json: X and Z rotation (deg)
and translation (mm); the laser plane as the largest distance between the estimated and
the true plane over the part of the true plane in view at stand-offs 80-130 mm.
Each of our median errors must be at most half of the better OpenCV method's.

The printed table is recorded in docs/results/calibration.md
(`STRIPECAL_OPENCV_SEEDS=10 python -m pytest tests/test_calib_opencv.py -s`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import stripecal
import stripecal.sim

cv2 = pytest.importorskip("cv2")

F64 = npt.NDArray[np.float64]
SEEDS = range(int(os.environ.get("STRIPECAL_OPENCV_SEEDS", "3")))


def make(r: F64, t: F64) -> F64:
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = np.ravel(t)
    return m


def iso_err(est: F64, truth: F64) -> Tuple[float, float]:
    r = est[:3, :3].T @ truth[:3, :3]
    ang = float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1.0, 1.0))))
    return ang, float(np.linalg.norm(est[:3, 3] - truth[:3, 3]))


def plane_err(cam: stripecal.Camera, truth: Tuple[F64, float], est: Tuple[F64, float]) -> float:
    """Largest |distance| from the estimated plane of true-plane points in view at
    stand-offs 80-130 mm."""
    uu, vv = np.meshgrid(np.linspace(0, cam.width - 1, 41), np.linspace(0, cam.height - 1, 31))
    rays = cam.unproject(np.stack([uu.ravel(), vv.ravel()], axis=1))
    n, d = truth
    s = d / (rays @ n)
    p = rays * s[:, None]
    p = p[(p[:, 2] >= 80) & (p[:, 2] <= 130)]
    ne, de = est
    return float(np.max(np.abs(p @ ne - de)))


def opencv_pipeline(path: Path, ours: stripecal.Calibration) -> Dict[str, Dict[str, Any]]:
    ds = stripecal.load_dataset(path)
    board = ds.rig.board
    centers3 = np.ascontiguousarray(board.centers(), np.float32)  # (N, 3), z = 0
    index_of = {(int(r), int(c)): k for k, (r, c) in enumerate(board.indices())}
    obj, img, used = [], [], []
    for i, name in enumerate(ds.board_images):
        im = stripecal.load_image(path / name)
        ok, c = cv2.findCirclesGrid(im, (board.cols, board.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
        if not ok:
            continue
        c = np.asarray(c, np.float64).reshape(-1, 2)
        idx, ctr = stripecal.detect_circles(im, board)
        d = np.linalg.norm(c[:, None, :] - ctr[None, :, :], axis=2)
        near = d.argmin(axis=1)
        keep = d[np.arange(len(c)), near] < 2.0
        rows = [index_of[(int(idx[j, 0]), int(idx[j, 1]))] for j in near[keep]]
        obj.append(centers3[rows])
        img.append(c[keep].astype(np.float32))
        used.append(i)
    flags = cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    w, h = ds.rig.width, ds.rig.height
    _, k, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, (w, h), None, None, flags=flags)
    cam = stripecal.Camera(w, h, k[0, 0], k[1, 1], k[0, 2], k[1, 2], "radial1", [dist.ravel()[0], 0, 0, 0, 0])
    cam_board = [make(cv2.Rodrigues(r)[0], t) for r, t in zip(rvecs, tvecs)]
    # The same stripe points ours used on the board, per view.
    sr = ours.stripe_residuals
    stripes = [sr[sr[:, 0] == i][:, 1:3] for i in used]
    fit = stripecal.fit_laser_plane(np.array(cam_board), stripes, cam)
    base_hand = ds.base_hand()[used]
    b2g = [np.linalg.inv(a) for a in base_hand]
    out: Dict[str, Dict[str, Any]] = {}
    for name, method in (("LI", cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI), ("SHAH", cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH)):
        r_b2w, t_b2w, r_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
            [m[:3, :3] for m in cam_board], [m[:3, 3].reshape(3, 1) for m in cam_board],
            [m[:3, :3] for m in b2g], [m[:3, 3].reshape(3, 1) for m in b2g], method=method,
        )
        out[name] = {
            "X": np.linalg.inv(make(r_g2c, t_g2c)),
            "Z": np.linalg.inv(make(r_b2w, t_b2w)),
            "plane": (np.asarray(fit["normal"]), float(fit["d_mm"])),
            "camera": cam,
        }
    return out


def test_one_stage_halves_the_opencv_pipeline_errors(tmp_path: Path) -> None:
    keys = ["X deg", "X mm", "Z deg", "Z mm", "plane mm"]
    rows: Dict[str, List[List[float]]] = {"stripecal one-stage": [], "OpenCV LI": [], "OpenCV SHAH": []}
    for seed in SEEDS:
        out = tmp_path / f"s{seed}"
        stripecal.sim.Twin(stripecal.sim.preset("hp3-paper", seed=seed, poses={"count": 15}, scan={"enabled": False})).write(out)
        path = out / "calib"
        truth = stripecal.load_truth(path / "truth.json")
        ours = stripecal.calibrate(path)
        tp = truth.laser_plane

        def errs(x: F64, z: F64, plane: Tuple[F64, float]) -> List[float]:
            return [*iso_err(x, truth.hand_cam), *iso_err(z, truth.base_board), plane_err(truth.camera, tp, plane)]

        n, d = ours.laser_plane
        rows["stripecal one-stage"].append(errs(ours.hand_cam, ours.base_board, (n, d)))
        for name, r in opencv_pipeline(path, ours).items():
            rows[f"OpenCV {name}"].append(errs(r["X"], r["Z"], r["plane"]))
    med = {k: np.median(np.array(v), axis=0) for k, v in rows.items()}
    print(f"\nmedian over {len(SEEDS)} seeds, 15 poses (hp3-paper, noise 1, PSF 0.7):")
    print("| pipeline | " + " | ".join(keys) + " |")
    print("|---" * (len(keys) + 1) + "|")
    for k, m in med.items():
        print(f"| {k} | " + " | ".join(f"{x:.4f}" for x in m) + " |")
    best_cv = np.minimum(med["OpenCV LI"], med["OpenCV SHAH"])
    ratio = med["stripecal one-stage"] / best_cv
    print("| ours / better OpenCV | " + " | ".join(f"{x:.2f}" for x in ratio) + " |")
    for k, r in zip(keys, ratio):
        assert r <= 0.5, f"{k}: ours is {r:.2f} of the better OpenCV method (need <= 0.5)"
