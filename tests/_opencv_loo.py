"""OpenCV's leave-one-view-out reference for the real data sets (issue 12).

Everything here is independent of stripecal's calibration: the poses are parsed with
numpy, the camera is cv2.calibrateCamera, the hand-eye X = T_hand_cam and the robot-world
Z = T_base_board are cv2.calibrateRobotWorldHandEye (SHAH). Only the detected target
points come from stripecal.detect_target, and the SAME points go to both tools.

Notation (../shared/spec/DATASET.md, "Units and frames"): A_i = T_base_hand of view i
(mm), X = T_hand_cam, Z = T_base_board, and for every view
T_cam_board(i) = (A_i X)^-1 Z. Pixel (0, 0)'s centre is at (0, 0) in both stripecal and
OpenCV, so detected points go to OpenCV unchanged.

Held-out definition (the same as stripecal's `leave_one_out` in calibration.json): for
each view k, calibrate without k; predict T_cam_board(k) from A_k alone with that
calibration's X, Z and camera; project view k's board points (cv2.projectPoints with the
distortion) and compare with its detected points:
- board_rms_px: RMS over the view's points of the 2-D error length;
- board_rms_mm: each detected pixel undistorted to a ray and intersected with the
  predicted board plane; RMS of the distance to the predicted 3-D board point (mm).
"""

from __future__ import annotations

import csv
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np
import numpy.typing as npt

import stripecal

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]


# ---------------------------------------------------------------------------------------
# rigid transforms and pose parsing (numpy only)


def make(r: npt.ArrayLike, t: npt.ArrayLike) -> F64:
    m = np.eye(4)
    m[:3, :3] = np.asarray(r, np.float64)
    m[:3, 3] = np.ravel(np.asarray(t, np.float64))
    return m


def inv(m: F64) -> F64:
    r = m[:3, :3]
    return make(r.T, -r.T @ m[:3, 3])


def rotvec_to_matrix(rv: npt.ArrayLike) -> F64:
    """Rodrigues: rotation vector (axis times angle, rad) to a rotation matrix."""
    w = np.asarray(rv, np.float64)
    th = float(np.linalg.norm(w))
    if th < 1e-12:
        return np.eye(3)
    k = w / th
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    r: F64 = np.eye(3) + np.sin(th) * kx + (1.0 - np.cos(th)) * (kx @ kx)
    return r


def quat_to_matrix(w: float, x: float, y: float, z: float) -> F64:
    """Unit Hamilton quaternion (w, x, y, z) to a rotation matrix."""
    n = np.sqrt(w * w + x * x + y * y + z * z)
    assert abs(n - 1.0) < 1e-3, f"quaternion norm {n}"
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def angle_deg(r: F64) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))


def pose_of_row(row: Dict[str, str]) -> F64:
    """T_base_hand (mm) from one views.csv row, by the column names: translation in m or
    mm; rotation as a quaternion (columns named, so ROS's x, y, z, w order is read by
    name) or a rotation vector in rad or deg."""
    if "x_m" in row:
        t = 1000.0 * np.array([float(row[k]) for k in ("x_m", "y_m", "z_m")])
    else:
        t = np.array([float(row[k]) for k in ("x_mm", "y_mm", "z_mm")])
    if "qw" in row:
        r = quat_to_matrix(*(float(row[k]) for k in ("qw", "qx", "qy", "qz")))
    elif "rx_rad" in row:
        r = rotvec_to_matrix([float(row[k]) for k in ("rx_rad", "ry_rad", "rz_rad")])
    elif "rx_deg" in row:
        r = rotvec_to_matrix(np.radians([float(row[k]) for k in ("rx_deg", "ry_deg", "rz_deg")]))
    else:
        raise ValueError(f"no rotation columns I know in {sorted(row)}")
    return make(r, t)


# ---------------------------------------------------------------------------------------
# the data set and its detections


def board_of(rig: Dict[str, Any]) -> stripecal.Board:
    b = rig["board"]
    if b.get("kind") == "chessboard":
        return stripecal.Board.chessboard(b["rows"], b["cols"], b["square_mm"])
    return stripecal.Board(
        b["rows"],
        b["cols"],
        b["pitch_mm"],
        b["circle_diameter_mm"],
        b.get("marker_diameter_mm"),
        markers=[tuple(m) for m in b.get("markers", [])],
        dark_circles=b.get("dark_circles", True),
    )


def board_points(indices: I64, rig: Dict[str, Any]) -> F64:
    """Board coordinates (mm) of the points (row, col): the contract's "Board" section
    (x along columns, y along rows, z = 0)."""
    b = rig["board"]
    kind = b.get("kind", "circles")
    r = indices[:, 0].astype(np.float64)
    c = indices[:, 1].astype(np.float64)
    if kind == "chessboard":
        s = float(b["square_mm"])
        return np.stack([c * s, r * s, np.zeros_like(r)], axis=1)
    p = float(b["pitch_mm"])
    if kind == "asymmetric_circles":
        return np.stack([(2 * c + np.mod(r, 2)) * p / 2, r * p / 2, np.zeros_like(r)], axis=1)
    return np.stack([c * p, r * p, np.zeros_like(r)], axis=1)


def half_turn(indices: I64, rows: int, cols: int) -> I64:
    """The labelling after a half turn of the board's point grid: (r, c) -> (R-1-r, C-1-c)."""
    return np.stack([rows - 1 - indices[:, 0], cols - 1 - indices[:, 1]], axis=1)


@dataclass
class View:
    row: int  # views.csv data row, 0-based
    image: Path
    A: F64  # T_base_hand, mm
    points: F64  # detected (u, v), px
    candidates: List[I64]  # labellings to choose from; [0] is the detection's
    indices: I64 = field(default_factory=lambda: np.zeros((0, 2), np.int64))  # the chosen one


@dataclass
class RealSet:
    name: str
    rig: Dict[str, Any]
    size: Tuple[int, int]
    flags: int
    views: List[View]
    labelling_note: str = ""
    # the labelling combinations tried, best first: (predicted RMS px, per-view choice)
    labelling_scores: List[Tuple[float, Tuple[int, ...]]] = field(default_factory=list)

    def obj(self, v: View) -> F64:
        return board_points(v.indices, self.rig)


def distortion_flags(model: str) -> int:
    """cv2.calibrateCamera flags for the rig's distortion model (DATASET.md "Camera
    model"): radial1 = k1; radial2 = k1, k2; opencv5 = all five."""
    if model == "radial1":
        return cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "radial2":
        return cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "opencv5":
        return 0
    raise ValueError(model)


def load_set(root: Path) -> RealSet:
    rig = json.loads((root / "rig.json").read_text())
    board = board_of(rig)
    cam = rig["camera"]
    views: List[View] = []
    with open(root / "views.csv", newline="") as f:
        for i, row in enumerate(csv.DictReader(f)):
            img = root / row["board_image"]
            det = stripecal.detect_target(stripecal.load_image(str(img)), board)
            cands = [np.asarray(det.indices, np.int64)]
            cands += [np.asarray(det.relabel(k), np.int64) for k in range(len(det.alternatives))]
            if board.kind == "chessboard":
                # every chessboard's corner grid looks the same after a half turn; the
                # detector tells the two apart by the colours (rows + cols odd), the
                # robot is asked independently here
                ht = half_turn(cands[0], board.rows, board.cols)
                if not any(_same_labelling(ht, c) for c in cands):
                    cands.append(ht)
            views.append(View(i, img, pose_of_row(row), np.asarray(det.points, np.float64), cands))
    s = RealSet(root.name, rig, (int(cam["width"]), int(cam["height"])),
                distortion_flags(cam.get("distortion_model", "radial1")), views)
    resolve_labelling(s)
    return s


def _same_labelling(a: I64, b: I64) -> bool:
    return a.shape == b.shape and bool(np.all(a == b))


# ---------------------------------------------------------------------------------------
# OpenCV: camera, robot-world/hand-eye, prediction


@dataclass
class Calib:
    K: F64
    dist: F64
    rms: float  # calibrateCamera's reprojection RMS, px
    T_cam_board: List[F64]  # calibrateCamera's extrinsics, per view used
    X: F64  # T_hand_cam
    Z: F64  # T_base_board


def calibrate_camera(s: RealSet, views: Sequence[View]) -> Tuple[float, F64, F64, List[F64]]:
    obj = [s.obj(v).astype(np.float32) for v in views]
    img = [v.points.astype(np.float32) for v in views]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, s.size, None, None, flags=s.flags, criteria=crit)
    T = [make(cv2.Rodrigues(r)[0], t) for r, t in zip(rvecs, tvecs)]
    return float(rms), np.asarray(K, np.float64), np.asarray(dist, np.float64).ravel(), T


def robot_world_hand_eye(T_cam_board: Sequence[F64], A: Sequence[F64]) -> Tuple[F64, F64]:
    """X = T_hand_cam, Z = T_base_board from cv2.calibrateRobotWorldHandEye (SHAH).

    OpenCV's inputs are world2cam = cTw = T_cam_board (world = board) and
    base2gripper = gTb = T_base_hand^-1; it solves cTw * wTb = cTg * gTb and returns
    base2world = wTb and gripper2cam = cTg. So Z = T_base_board = wTb^-1 and
    X = T_hand_cam = cTg^-1 (checked in the tests: (A_i X)^-1 Z reproduces the
    calibrateCamera poses)."""
    g = [inv(a) for a in A]
    rb2w, tb2w, rg2c, tg2c = cv2.calibrateRobotWorldHandEye(
        [t[:3, :3] for t in T_cam_board],
        [t[:3, 3].reshape(3, 1) for t in T_cam_board],
        [m[:3, :3] for m in g],
        [m[:3, 3].reshape(3, 1) for m in g],
        method=cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH,
    )
    wTb = make(np.asarray(rb2w, np.float64), np.asarray(tb2w, np.float64))
    cTg = make(np.asarray(rg2c, np.float64), np.asarray(tg2c, np.float64))
    return inv(cTg), inv(wTb)


def predict(A: F64, X: F64, Z: F64) -> F64:
    """T_cam_board of a view from its robot pose alone: (A X)^-1 Z."""
    return inv(A @ X) @ Z


def calibrate(s: RealSet, views: Sequence[View]) -> Calib:
    rms, K, dist, T = calibrate_camera(s, views)
    X, Z = robot_world_hand_eye(T, [v.A for v in views])
    return Calib(K, dist, rms, T, X, Z)


def view_errors(K: F64, dist: F64, T: F64, obj: F64, pts: F64) -> Tuple[float, float]:
    """(board_rms_px, board_rms_mm) of detected points `pts` against board points `obj`
    seen from the board pose T = T_cam_board (the held-out definition above)."""
    rvec = cv2.Rodrigues(T[:3, :3])[0]
    proj, _ = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, T[:3, 3].reshape(3, 1), K, dist)
    d = proj.reshape(-1, 2) - pts
    rms_px = float(np.sqrt(np.mean(np.sum(d * d, axis=1))))
    # the detected pixel's ray meets the predicted board plane n . p = n . t
    xn = cv2.undistortPoints(pts.reshape(-1, 1, 2), K, dist).reshape(-1, 2)
    rays = np.hstack([xn, np.ones((len(xn), 1))])
    n, t = T[:3, 2], T[:3, 3]
    hit = rays * ((n @ t) / (rays @ n))[:, None]
    pred = obj @ T[:3, :3].T + t
    e = hit - pred
    rms_mm = float(np.sqrt(np.mean(np.sum(e * e, axis=1))))
    return rms_px, rms_mm


def in_sample(s: RealSet, c: Calib, views: Sequence[View]) -> Dict[str, float]:
    """How consistent AX = ZB is on the views it was solved from: the predicted board
    poses against calibrateCamera's (rotation deg, translation mm, RMS over views) and
    the predicted reprojection RMS (px, over all points)."""
    rot, tr, sq, n = [], [], 0.0, 0
    for v, T in zip(views, c.T_cam_board):
        P = predict(v.A, c.X, c.Z)
        rot.append(angle_deg(P[:3, :3].T @ T[:3, :3]))
        tr.append(float(np.linalg.norm(P[:3, 3] - T[:3, 3])))
        px, _ = view_errors(c.K, c.dist, P, s.obj(v), v.points)
        sq += px * px * len(v.points)
        n += len(v.points)
    return {
        "pose_rot_rms_deg": float(np.sqrt(np.mean(np.square(rot)))),
        "pose_trans_rms_mm": float(np.sqrt(np.mean(np.square(tr)))),
        "pose_rot_max_deg": float(np.max(rot)),
        "pose_trans_max_mm": float(np.max(tr)),
        "predicted_rms_px": float(np.sqrt(sq / n)),
    }


def resolve_labelling(s: RealSet) -> None:
    """Chooses each view's labelling among its candidates (the detection's, its
    alternatives and, for a chessboard, the half turn) so that AX = ZB is most
    consistent: brute force over the combinations, the first view's labelling fixed to
    the detection's (the one overall choice left only turns Z). The score is the
    reprojection RMS of every view's board points predicted from its robot pose by
    SHAH's X, Z (OpenCV's camera from the detection's labelling: a view's relabelling
    under a symmetry of its points changes only that view's free pose, not the camera).
    This mirrors what stripecal's consensus does (each view's labelling chosen to agree
    with the robot poses of the others, the first view fixing the frame), independently.
    It is decided once on all views, the held-out one included, as the consensus is: a
    discrete choice that the leave-one-out figures do not depend on when it is clear (on
    visp_franka the runner-up is off by hundreds of pixels)."""
    views = s.views
    for v in views:
        v.indices = v.candidates[0]
    choices = [range(1)] + [range(len(v.candidates)) for v in views[1:]]
    combos = list(itertools.product(*choices))
    if len(combos) == 1:
        s.labelling_note = "one labelling per view (no symmetry left by the detection)"
        return
    _, K, dist, _ = calibrate_camera(s, views)
    poses: List[List[F64]] = []
    for v in views:
        ps = []
        for cand in v.candidates:
            ok, rv, tv = cv2.solvePnP(board_points(cand, s.rig), v.points, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
            assert ok
            ps.append(make(cv2.Rodrigues(rv)[0], tv))
        poses.append(ps)
    scored: List[Tuple[float, Tuple[int, ...]]] = []
    for combo in combos:
        T = [poses[i][k] for i, k in enumerate(combo)]
        X, Z = robot_world_hand_eye(T, [v.A for v in views])
        sq, n = 0.0, 0
        for v, k in zip(views, combo):
            px, _ = view_errors(K, dist, predict(v.A, X, Z), board_points(v.candidates[k], s.rig), v.points)
            sq += px * px * len(v.points)
            n += len(v.points)
        scored.append((float(np.sqrt(sq / n)), combo))
    scored.sort(key=lambda x: x[0])
    best, combo = scored[0]
    for v, k in zip(views, combo):
        v.indices = v.candidates[k]
    s.labelling_scores = scored
    s.labelling_note = (
        f"{len(combos)} combinations; best predicted RMS {best:.2f} px with labelling "
        f"{list(combo)} (0 = the detection's), next {scored[1][0]:.2f} px with {list(scored[1][1])}"
    )


# ---------------------------------------------------------------------------------------
# leave one view out, and the board scale the robot implies


def leave_one_out(s: RealSet, rows: Optional[Sequence[int]] = None) -> Dict[str, Any]:
    """OpenCV's held-out figures over the views whose views.csv rows are `rows` (all
    views by default): each one predicted by a calibration from the others of `rows`."""
    use = [v for v in s.views if rows is None or v.row in set(rows)]
    out = []
    for k, held in enumerate(use):
        c = calibrate(s, use[:k] + use[k + 1:])
        px, mm = view_errors(c.K, c.dist, predict(held.A, c.X, c.Z), s.obj(held), held.points)
        out.append({"view": held.row, "points": len(held.points), "board_rms_px": px, "board_rms_mm": mm})
    return {
        "views": out,
        "median_board_rms_px": float(np.median([o["board_rms_px"] for o in out])),
        "median_board_rms_mm": float(np.median([o["board_rms_mm"] for o in out])),
    }


def implied_scale(s: RealSet, c: Calib) -> Tuple[float, float, float]:
    """The board scale the robot implies: with SHAH's rotations fixed, the translation
    part of A_i X B_i = Z (B_i = T_cam_board(i)) with B_i's translation scaled by s,
    s R_A R_X t_B + R_A t_X - t_Z = -t_A, is linear in (s, t_X, t_Z). Returns s and the
    RMS translation residual (mm) at s and at s = 1 (t_X, t_Z refitted)."""
    rows, rhs = [], []
    for v, B in zip(s.views, c.T_cam_board):
        ra = v.A[:3, :3]
        m = np.zeros((3, 7))
        m[:, 0] = ra @ c.X[:3, :3] @ B[:3, 3]
        m[:, 1:4] = ra
        m[:, 4:7] = -np.eye(3)
        rows.append(m)
        rhs.append(-v.A[:3, 3])
    M, b = np.vstack(rows), np.concatenate(rhs)
    sol, *_ = np.linalg.lstsq(M, b, rcond=None)
    res_s = float(np.sqrt(np.mean((M @ sol - b) ** 2) * 3))
    sol1, *_ = np.linalg.lstsq(M[:, 1:], b - M[:, 0], rcond=None)
    res_1 = float(np.sqrt(np.mean((M[:, 1:] @ sol1 - (b - M[:, 0])) ** 2) * 3))
    return float(sol[0]), res_s, res_1
