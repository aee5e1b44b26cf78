#!/usr/bin/env python3
"""An independent OpenCV reference for the laser plane on the real etna data sets.

Everything here is numpy + OpenCV; stripecal is NOT imported (this is the peer that
stripecal's figures are compared with). Conventions (../../../shared/spec/DATASET.md):
lengths in mm, T_a_b maps frame b to frame a, A_i = T_base_hand of view i, the hand-eye
X = T_hand_cam, the robot-world Z = T_base_board, and for every view
T_cam_board(i) = (A_i X)^-1 Z. Pixel (0, 0)'s centre is at (0, 0) (OpenCV's convention:
corners and centroids go to OpenCV unchanged).

Stages:
1. Plain stripe extractor (DECISIONS 8): a morphological top-hat ACROSS the line, one
   intensity centroid per scan line over the top-hat's run above half that line's
   maximum, then the dominant straight line through the centroids (RANSAC, a few px):
   the sheet's points up to its depth step.
2. The multi-stage recipe: findChessboardCorners + cornerSubPix, calibrateCamera with
   the rig's distortion model, solvePnP per view, hand-eye by calibrateHandEye (PARK,
   with Z averaged from A_i X B_i) or calibrateRobotWorldHandEye (SHAH), and the laser
   plane as the total-least-squares plane through the stripe points back-projected
   onto each view's board plane (camera frame).
3. Leave one view out (DECISIONS 3 and 8): for each view k, the recipe without k
   predicts (a) k's board corners from its robot pose alone (chain error, px and mm)
   and (b) the board plane that k's plain stripe points, triangulated with the fold's
   camera and laser plane and mapped to the base by A_k X, should lie on (mm).
4. Per-view descriptions of the real line: saturation, width, second bright runs
   (reflections), speckle jitter, and the depth step.

Run:  python3 recipe.py                   (both etna data sets)
      python3 recipe.py --dataset etna_calib4 --tol 3
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional, Sequence, Tuple

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
REALDATA = HERE.parents[2] / "shared" / "realdata"  # ../shared/realdata beside the clone
DATASETS = ("etna_calib3", "etna_calib4")

# --- plain extractor settings (DECISIONS 8) ---------------------------------------------
TOPHAT_WIDTH = 61  # px across the line; the saturated core is ~16-22 px, its base ~30-40
MIN_PEAK = 30.0  # a scan line whose top-hat maximum is below this has no line (grey levels)
REL_THRESHOLD = 0.5  # the centroid's run: top-hat above this fraction of the line's maximum
RANSAC_TOL_PX = 3.0  # inlier band around the dominant straight line (perpendicular px)
RANSAC_ITERS = 2000
RANSAC_SEED = 0  # the extractor is deterministic

# --- chessboard ------------------------------------------------------------------------
SUBPIX_WIN = (5, 5)  # cornerSubPix half window (px); squares are ~35-110 px in these images

# --- phenomena settings (item 5) ---------------------------------------------------------
SAT_LEVEL = 255  # a pixel at this grey level is saturated (8-bit images)
MIN_RUN_PX = 3  # a separate bright run narrower than this is speckle, not a reflection
WIDE_RUN_PX = 8  # a separate run at least this wide is a substantial second line


# =========================================================================================
# rigid transforms and pose parsing (numpy only; as tests/_opencv_loo.py)


def make(r: np.ndarray, t: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = np.asarray(r, np.float64)
    m[:3, 3] = np.ravel(np.asarray(t, np.float64))
    return m


def inv(m: np.ndarray) -> np.ndarray:
    r = m[:3, :3]
    return make(r.T, -r.T @ m[:3, 3])


def quat_to_matrix(w: float, x: float, y: float, z: float) -> np.ndarray:
    """Unit Hamilton quaternion (w, x, y, z) to a rotation matrix (norm checked, as the
    contract asks, never silently normalised away)."""
    n = np.sqrt(w * w + x * x + y * y + z * z)
    if abs(n - 1.0) > 1e-3:
        raise ValueError(f"quaternion norm {n}")
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def pose_of_row(row: Dict[str, str]) -> np.ndarray:
    """T_base_hand (mm) of one views.csv row, read by column NAME: etna_calib3 has
    x_mm,y_mm,z_mm,qw,qx,qy,qz; etna_calib4 x_m,y_m,z_m,qx,qy,qz,qw (ROS order)."""
    if "x_m" in row:
        t = 1000.0 * np.array([float(row[k]) for k in ("x_m", "y_m", "z_m")])
    else:
        t = np.array([float(row[k]) for k in ("x_mm", "y_mm", "z_mm")])
    if "qw" not in row:
        raise ValueError(f"no quaternion columns in {sorted(row)}")
    r = quat_to_matrix(*(float(row[k]) for k in ("qw", "qx", "qy", "qz")))
    return make(r, t)


def rot_angle_deg(r: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))))


def project_to_rotation(m: np.ndarray) -> np.ndarray:
    """The rotation nearest to m (Frobenius): the chordal mean of rotations summed in m."""
    u, _, vt = np.linalg.svd(m)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


# =========================================================================================
# the data set


@dataclass
class View:
    row: int  # 0-based index of the views.csv data row
    image: str  # the path as views.csv names it (relative to the data set folder)
    A: np.ndarray  # T_base_hand, mm
    gray: np.ndarray  # BT.601 luma, uint8
    corners: Optional[np.ndarray] = None  # (rows*cols, 2) px, board order; None: no board
    corner_note: str = ""
    stripe: Optional["Stripe"] = None


@dataclass
class DataSet:
    name: str
    rig: Dict
    size: Tuple[int, int]  # (width, height)
    views: List[View]
    obj: np.ndarray  # (rows*cols, 3) board coordinates (mm), the corners' order

    def with_board(self) -> List[View]:
        return [v for v in self.views if v.corners is not None]


def board_object_points(rows: int, cols: int, square: float) -> np.ndarray:
    """Corner (r, c) at (c*square, r*square, 0), row-major (the contract's "Board")."""
    r, c = np.mgrid[0:rows, 0:cols]
    return np.stack([c.ravel() * square, r.ravel() * square, np.zeros(rows * cols)], axis=1)


def set_realdata(path: Path) -> None:
    global REALDATA
    REALDATA = Path(path)


def load(name: str) -> DataSet:
    root = REALDATA / name
    rig = json.loads((root / "rig.json").read_text())
    b = rig["board"]
    assert b.get("kind") == "chessboard", b
    rows, cols, sq = int(b["rows"]), int(b["cols"]), float(b["square_mm"])
    views = []
    with open(root / "views.csv", newline="") as f:
        for i, row in enumerate(csv.DictReader(f)):
            assert row["laser_image"] == row["board_image"], "etna: one image holds both"
            img = cv2.imread(str(root / row["board_image"]), cv2.IMREAD_COLOR)
            gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)  # BT.601 luma
            views.append(View(i, row["board_image"], pose_of_row(row), gray))
    size = (int(rig["camera"]["width"]), int(rig["camera"]["height"]))
    ds = DataSet(name, rig, size, views, board_object_points(rows, cols, sq))
    for v in views:
        v.corners, v.corner_note = detect_chessboard(v.gray, rows, cols)
    return ds


# =========================================================================================
# chessboard corners (OpenCV), labelled by the contract


def detect_chessboard(gray: np.ndarray, rows: int, cols: int) -> Tuple[Optional[np.ndarray], str]:
    """Inner corners in the contract's order: corner (r, c) at index r*cols + c, board
    x along increasing c, y along increasing r, z = x cross y into the plate (away from
    the camera), and the square outside corner (0, 0) dark.

    cv2.findChessboardCorners takes patternSize = (points per row, points per column) =
    (cols, rows) and returns the corners row by row, but it may start at any corner of
    the grid; the handedness (z away from the camera) and the colours (7 + 6 is odd, so
    a half turn swaps dark and light) fix the labelling here. At full resolution the
    detector fails on etna_calib3 frame0013 (the board's outer squares are cut by the
    image border and the laser crosses a corner square); a detection at half resolution,
    scaled back and refined by cornerSubPix at full resolution, finds it."""
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    note = "full resolution"
    ok, c = cv2.findChessboardCorners(gray, (cols, rows), flags)
    if not ok:
        half = cv2.resize(gray, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        ok, c = cv2.findChessboardCorners(half, (cols, rows), flags)
        if not ok:
            return None, "not found"
        # pixel centres: full-resolution u = 2 * half-resolution u + 0.5
        c = c * 2.0 + 0.5
        note = "half resolution, refined at full"
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-3)
    c = cv2.cornerSubPix(gray, c.astype(np.float32), SUBPIX_WIN, (-1, -1), crit)
    g = c.reshape(rows, cols, 2).astype(np.float64)
    # handedness: seen from the camera (u right, v down, z forward), board x then y turn
    # clockwise on screen, i.e. cross(x_img, y_img) > 0, when z points away
    ex, ey = g[0, -1] - g[0, 0], g[-1, 0] - g[0, 0]
    if ex[0] * ey[1] - ex[1] * ey[0] < 0:
        g = g[:, ::-1]
        note += ", mirrored"
    if _colour_score(gray, g) < 0:
        g = g[::-1, ::-1]
        note += ", half turn"
    return g.reshape(-1, 2), note


def _colour_score(gray: np.ndarray, g: np.ndarray) -> float:
    """Positive when the squares dark by the contract (the one outside corner (0, 0) and
    every second one from it) are darker than the others: the median grey of every
    square centre, mapped through the board->image homography, correlated with the
    expected pattern (squares cut by the image border are skipped)."""
    rows, cols = g.shape[:2]
    src = np.stack(np.meshgrid(np.arange(cols), np.arange(rows)), axis=-1).reshape(-1, 2)
    H, _ = cv2.findHomography(src.astype(np.float64), g.reshape(-1, 2))
    score = []
    for j in range(rows + 1):  # square j spans board y in [j-1, j] squares
        for i in range(cols + 1):
            p = cv2.perspectiveTransform(np.array([[[i - 0.5, j - 0.5]]]), H)[0, 0]
            u, v = int(round(p[0])), int(round(p[1]))
            if 3 <= u < gray.shape[1] - 3 and 3 <= v < gray.shape[0] - 3:
                val = float(np.median(gray[v - 3 : v + 4, u - 3 : u + 4]))
                dark = (i + j) % 2 == 0
                score.append((val, 1.0 if dark else -1.0))
    vals = np.array([s[0] for s in score])
    sign = np.array([s[1] for s in score])
    return float(-np.sum((vals - vals.mean()) * sign))


# =========================================================================================
# 1. the plain stripe extractor (DECISIONS 8)


@dataclass
class Stripe:
    """Per-scan-line measurements and the kept points of one image."""

    scan: np.ndarray  # scan line index (image row for direction "cols") of every centroid
    pos: np.ndarray  # centroid along the scan line (image column), px
    peak: np.ndarray  # the line's top-hat maximum, grey levels
    width: np.ndarray  # the run's length above REL_THRESHOLD * peak, px ("FWHM")
    base: np.ndarray  # the length of the run through the maximum above 10 % of the peak, px
    plateau: np.ndarray  # saturated pixels in the run
    run_sat: np.ndarray  # saturated share of the run's pixels
    runs: List[List[Tuple[int, int]]]  # every run above the threshold: (start, end excl.)
    keep: np.ndarray  # bool: on the dominant straight line (RANSAC inlier)
    line: Tuple[np.ndarray, float]  # unit normal n and c: n . (u, v) = c
    resid: np.ndarray  # signed distance of every centroid to the line, px
    direction: str = "cols"

    def uv(self, mask: Optional[np.ndarray] = None) -> np.ndarray:
        """(u, v) pixel coordinates (u = column, v = row) of the centroids in mask."""
        m = self.keep if mask is None else mask
        if self.direction == "cols":
            return np.stack([self.pos[m], self.scan[m].astype(np.float64)], axis=1)
        return np.stack([self.scan[m].astype(np.float64), self.pos[m]], axis=1)


def plain_extract(gray: np.ndarray, direction: str = "cols", tol: float = RANSAC_TOL_PX) -> Stripe:
    """The plain extractor: top-hat across the line, one centroid per scan line, the
    dominant straight line.

    direction "cols" (rig.json): the line runs along image columns, every image ROW is a
    scan line, so "across the line" is along a row and the top-hat's structuring element
    is 1 row x TOPHAT_WIDTH columns. For "rows" the image is transposed first."""
    img = gray if direction == "cols" else gray.T
    se = cv2.getStructuringElement(cv2.MORPH_RECT, (TOPHAT_WIDTH, 1))  # (width, height)
    th = cv2.morphologyEx(img, cv2.MORPH_TOPHAT, se).astype(np.float64)
    scan, pos, peak, width, base, plateau, run_sat, runs = [], [], [], [], [], [], [], []
    for v in range(th.shape[0]):
        t = th[v]
        k = int(np.argmax(t))
        m = t[k]
        if m < MIN_PEAK:
            continue
        thr = REL_THRESHOLD * m
        above = t > thr
        # the run through the maximum
        a = k
        while a > 0 and above[a - 1]:
            a -= 1
        b = k + 1
        while b < len(t) and above[b]:
            b += 1
        x = np.arange(a, b, dtype=np.float64)
        w = t[a:b]
        scan.append(v)
        pos.append(float(np.sum(x * w) / np.sum(w)))
        peak.append(m)
        width.append(b - a)
        base.append(_run_length(t > 0.1 * m, k))
        sat = img[v, a:b] >= SAT_LEVEL
        plateau.append(int(sat.sum()))
        run_sat.append(float(sat.mean()))
        runs.append(_runs(above))
    scan_a = np.asarray(scan, np.int64)
    pos_a = np.asarray(pos, np.float64)
    pts = np.stack([pos_a, scan_a.astype(np.float64)], axis=1) if len(scan) else np.zeros((0, 2))
    n, c, keep = ransac_line(pts, tol)
    resid = pts @ n - c if len(pts) else np.zeros(0)
    return Stripe(
        scan_a, pos_a, np.asarray(peak), np.asarray(width), np.asarray(base), np.asarray(plateau),
        np.asarray(run_sat), runs, keep, (n, c), resid, direction,
    )


def _run_length(mask: np.ndarray, k: int) -> int:
    """Length of the run of True in a 1-D mask through index k."""
    a, b = k, k + 1
    while a > 0 and mask[a - 1]:
        a -= 1
    while b < len(mask) and mask[b]:
        b += 1
    return b - a


def _runs(mask: np.ndarray) -> List[Tuple[int, int]]:
    """Maximal runs of True in a 1-D mask, as (start, end exclusive)."""
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def ransac_line(pts: np.ndarray, tol: float) -> Tuple[np.ndarray, float, np.ndarray]:
    """The dominant straight line through 2-D points: RANSAC on point pairs (the most
    points within tol, perpendicular), then two rounds of a total-least-squares refit on
    the inliers and re-selection. Returns the unit normal n, c with n . p = c, and the
    inlier mask."""
    N = len(pts)
    if N < 2:
        return np.array([1.0, 0.0]), 0.0, np.zeros(N, bool)
    rng = np.random.default_rng(RANSAC_SEED)
    best = np.zeros(N, bool)
    for _ in range(RANSAC_ITERS):
        i, j = rng.choice(N, 2, replace=False)
        d = pts[j] - pts[i]
        L = np.hypot(*d)
        if L < 1e-9:
            continue
        n = np.array([-d[1], d[0]]) / L
        inl = np.abs(pts @ n - n @ pts[i]) < tol
        if inl.sum() > best.sum():
            best = inl
    keep = best
    n, c = np.array([1.0, 0.0]), 0.0
    for _ in range(2):
        n, c = tls_line(pts[keep])
        keep = np.abs(pts @ n - c) < tol
    return n, c, keep


def tls_line(p: np.ndarray) -> Tuple[np.ndarray, float]:
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m, full_matrices=False)
    n = vt[-1]
    return n, float(n @ m)


# =========================================================================================
# 2. the multi-stage recipe


def distortion_flags(model: str) -> int:
    """calibrateCamera flags for the rig's model (DATASET.md "Camera model"): radial1 =
    k1; radial2 = k1, k2 (p1, p2, k3 fixed at 0); opencv5 = all five."""
    if model == "radial1":
        return cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "radial2":
        return cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "opencv5":
        return 0
    raise ValueError(model)


@dataclass
class Calib:
    K: np.ndarray
    dist: np.ndarray
    rms_px: float  # calibrateCamera's RMS
    B: List[np.ndarray]  # T_cam_board per view used (solvePnP with this camera)
    X: Dict[str, np.ndarray] = field(default_factory=dict)  # method -> T_hand_cam
    Z: Dict[str, np.ndarray] = field(default_factory=dict)  # method -> T_base_board
    plane: Tuple[np.ndarray, float] = (np.zeros(3), 0.0)  # n . p = d in the camera frame
    plane_rms_mm: float = 0.0
    plane_points: int = 0


def calibrate(ds: DataSet, views: Sequence[View], model: str) -> Calib:
    """The recipe on `views` (those with a board): camera, board poses, both hand-eye
    solutions, and the laser plane."""
    obj = [ds.obj.astype(np.float32) for _ in views]
    img = [v.corners.astype(np.float32) for v in views]
    crit = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, ds.size, None, None, flags=distortion_flags(model), criteria=crit)
    K, dist = np.asarray(K, np.float64), np.asarray(dist, np.float64).ravel()
    B = []
    for v in views:
        ok, rv, tv = cv2.solvePnP(ds.obj, v.corners, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
        assert ok
        B.append(make(cv2.Rodrigues(rv)[0], tv))
    c = Calib(K, dist, float(rms), B)
    A = [v.A for v in views]
    c.X["PARK"], c.Z["PARK"] = hand_eye_park(A, B)
    c.X["SHAH"], c.Z["SHAH"] = robot_world_hand_eye_shah(A, B)
    c.plane, c.plane_rms_mm, c.plane_points = fit_laser_plane(c, views)
    return c


def hand_eye_park(A: Sequence[np.ndarray], B: Sequence[np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """X = T_hand_cam by cv2.calibrateHandEye (PARK): its inputs are gripper2base =
    T_base_hand = A_i and target2cam = T_cam_board = B_i, its output cam2gripper =
    T_hand_cam. calibrateHandEye gives no Z: Z = T_base_board is the mean of A_i X B_i
    (chordal mean of the rotations, mean of the translations)."""
    R, t = cv2.calibrateHandEye(
        [a[:3, :3] for a in A], [a[:3, 3].reshape(3, 1) for a in A],
        [b[:3, :3] for b in B], [b[:3, 3].reshape(3, 1) for b in B],
        method=cv2.CALIB_HAND_EYE_PARK,
    )
    X = make(R, t)
    Zs = [a @ X @ b for a, b in zip(A, B)]
    Z = make(project_to_rotation(sum(z[:3, :3] for z in Zs)), np.mean([z[:3, 3] for z in Zs], axis=0))
    return X, Z


def robot_world_hand_eye_shah(A: Sequence[np.ndarray], B: Sequence[np.ndarray]) -> Tuple[np.ndarray, np.ndarray]:
    """X, Z from cv2.calibrateRobotWorldHandEye (SHAH). Its inputs are world2cam = cTw =
    T_cam_board (world = board) and base2gripper = gTb = A_i^-1; it solves
    cTw * wTb = cTg * gTb and returns base2world = wTb and gripper2cam = cTg, so
    Z = T_base_board = wTb^-1 and X = T_hand_cam = cTg^-1."""
    g = [inv(a) for a in A]
    rb2w, tb2w, rg2c, tg2c = cv2.calibrateRobotWorldHandEye(
        [b[:3, :3] for b in B], [b[:3, 3].reshape(3, 1) for b in B],
        [m[:3, :3] for m in g], [m[:3, 3].reshape(3, 1) for m in g],
        method=cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH,
    )
    return inv(make(rg2c, tg2c)), inv(make(rb2w, tb2w))


def rays(K: np.ndarray, dist: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Undistorted viewing rays (x_n, y_n, 1) of pixels (u, v)."""
    xn = cv2.undistortPoints(uv.reshape(-1, 1, 2).astype(np.float64), K, dist).reshape(-1, 2)
    return np.hstack([xn, np.ones((len(xn), 1))])


def hit_plane(r: np.ndarray, n: np.ndarray, d: float) -> np.ndarray:
    """Where the rays r (from the camera centre) meet the plane n . p = d."""
    return r * (d / (r @ n))[:, None]


def fit_laser_plane(c: Calib, views: Sequence[View]) -> Tuple[Tuple[np.ndarray, float], float, int]:
    """The laser plane (camera frame): each view's kept stripe points back-projected onto
    its board plane (from its solvePnP pose: normal R[:, 2], n . t), all views pooled,
    and the total-least-squares plane (SVD) through them; d > 0 as the contract asks."""
    P = []
    for v, B in zip(views, c.B):
        if v.stripe is None or not v.stripe.keep.any():
            continue
        n = B[:3, 2]
        P.append(hit_plane(rays(c.K, c.dist, v.stripe.uv()), n, float(n @ B[:3, 3])))
    P = np.vstack(P)
    m = P.mean(axis=0)
    _, _, vt = np.linalg.svd(P - m, full_matrices=False)
    n = vt[-1]
    d = float(n @ m)
    if d < 0:
        n, d = -n, -d
    return (n, d), float(np.sqrt(np.mean((P @ n - d) ** 2))), len(P)


# =========================================================================================
# 3. leave one view out


def chain_error(ds: DataSet, c: Calib, method: str, v: View) -> Tuple[float, float]:
    """DECISIONS 3: view v's board corners predicted from its robot pose alone,
    T_cam_board = (A X)^-1 Z; RMS px of the projected against the detected corners, and
    RMS mm on the predicted board plane (each detected pixel's ray meets that plane)."""
    T = inv(v.A @ c.X[method]) @ c.Z[method]
    rv = cv2.Rodrigues(T[:3, :3])[0]
    proj, _ = cv2.projectPoints(ds.obj.reshape(-1, 1, 3), rv, T[:3, 3].reshape(3, 1), c.K, c.dist)
    e = proj.reshape(-1, 2) - v.corners
    px = float(np.sqrt(np.mean(np.sum(e * e, axis=1))))
    n = T[:3, 2]
    hit = hit_plane(rays(c.K, c.dist, v.corners), n, float(n @ T[:3, 3]))
    e3 = hit - (ds.obj @ T[:3, :3].T + T[:3, 3])
    return px, float(np.sqrt(np.mean(np.sum(e3 * e3, axis=1))))


def laser_to_board(c: Calib, method: str, v: View) -> np.ndarray:
    """DECISIONS 8: view v's kept stripe points triangulated with the fold's camera and
    laser plane, mapped to the base by v's robot pose and the fold's hand-eye,
    p_base = A X p_cam, and their signed distance (mm) to the board plane the fold
    predicts: n = Z[:, 2] (board z, into the plate), through Z's origin."""
    n, d = c.plane
    p_cam = hit_plane(rays(c.K, c.dist, v.stripe.uv()), n, d)
    M = v.A @ c.X[method]
    p_base = p_cam @ M[:3, :3].T + M[:3, 3]
    Z = c.Z[method]
    return (p_base - Z[:3, 3]) @ Z[:3, 2]


@dataclass
class Fold:
    held: View
    calib: Calib
    chain: Dict[str, Tuple[float, float]]  # method -> (px, mm); empty without a board
    laser: Dict[str, np.ndarray]  # method -> signed distances, mm


def leave_one_out(ds: DataSet, model: str) -> List[Fold]:
    """For each view k with stripe points or a board: the recipe without k, and k's
    held-out figures. A view whose board is not found can still be held out for the
    laser figure (it needs only k's robot pose and stripe points)."""
    folds = []
    for held in ds.views:
        train = [v for v in ds.with_board() if v is not held]
        c = calibrate(ds, train, model)
        chain = {}
        if held.corners is not None:
            chain = {m: chain_error(ds, c, m, held) for m in ("PARK", "SHAH")}
        laser = {}
        if held.stripe is not None and held.stripe.keep.any():
            laser = {m: laser_to_board(c, m, held) for m in ("PARK", "SHAH")}
        folds.append(Fold(held, c, chain, laser))
    return folds


# =========================================================================================
# 4. what the real line looks like


def _bow(scan: np.ndarray, pos: np.ndarray) -> float:
    """Peak-to-peak of a quadratic fit's departure from a straight-line fit, px: how far
    the kept points bend over their span."""
    q = np.polyfit(scan, pos, 2)
    lin = np.polyfit(scan, pos, 1)
    bend = np.polyval(q, scan) - np.polyval(lin, scan)
    return float(bend.max() - bend.min())


def phenomena(s: Stripe, tol: float, K: Optional[np.ndarray] = None, dist: Optional[np.ndarray] = None) -> Dict:
    """Per-view description of the line (on the kept rows unless said otherwise). With a
    camera (K, dist), also the bow of the kept points after undistortion: what is left
    of the curvature once the lens is accounted for."""
    k = s.keep
    out: Dict = {"scan_lines_with_peak": int(len(s.scan)), "kept": int(k.sum())}
    if not k.any():
        return out
    # saturation and width over the kept rows
    out["saturated_share"] = float(np.sum(s.run_sat[k] * s.width[k]) / np.sum(s.width[k]))
    out["rows_with_saturation"] = float(np.mean(s.plateau[k] > 0))
    out["width_px_p5_50_95"] = np.percentile(s.width[k], [5, 50, 95]).tolist()
    out["plateau_px_p5_50_95"] = np.percentile(s.plateau[k], [5, 50, 95]).tolist()
    out["base_px_p5_50_95"] = np.percentile(s.base[k], [5, 50, 95]).tolist()  # above 10 %
    # second bright runs (above half the line's maximum, separate from the main run)
    main_centres = s.pos
    n_multi, n_wide, offsets = 0, 0, []
    for i, runs in enumerate(s.runs):
        others = [(a, b) for a, b in runs if b - a >= MIN_RUN_PX and not (a <= main_centres[i] < b)]
        if others:
            n_multi += 1
            off = [((a + b - 1) / 2 - main_centres[i]) for a, b in others]
            offsets.append(min(off, key=abs))
            if any(b - a >= WIDE_RUN_PX for a, b in others):
                n_wide += 1
    out["rows_two_runs"] = n_multi  # over all scan lines with a peak
    out["rows_two_runs_wide"] = n_wide
    out["second_run_offset_px_median_abs"] = float(np.median(np.abs(offsets))) if offsets else None
    # speckle: jitter of the kept centroids about a smooth curve (a quadratic in the
    # scan coordinate absorbs lens curvature), and the run intensity's variation
    sc = s.scan[k].astype(np.float64)
    pc = s.pos[k]
    q = np.polyfit(sc, pc, 2)
    out["jitter_rms_px"] = float(np.sqrt(np.mean((pc - np.polyval(q, sc)) ** 2)))
    # the high-frequency part alone: consecutive kept rows' differences / sqrt(2)
    nb = np.diff(sc) == 1
    out["jitter_row_to_row_px"] = float(np.sqrt(np.mean(np.diff(pc)[nb] ** 2) / 2.0)) if nb.any() else None
    out["bow_px"] = _bow(sc, pc)  # curvature over the kept span
    if K is not None:
        und = cv2.undistortPoints(s.uv().reshape(-1, 1, 2), K, dist, P=K).reshape(-1, 2)
        a, b = (1, 0) if s.direction == "cols" else (0, 1)
        out["bow_undistorted_px"] = _bow(und[:, a], und[:, b])
    out["line_resid_rms_px"] = float(np.sqrt(np.mean(s.resid[k] ** 2)))
    # the kept span and what lies beyond it (the depth step shifts the line sideways)
    lo, hi = int(sc.min()), int(sc.max())
    out["kept_span"] = [lo, hi]
    out["kept_fill"] = float(k.sum() / (hi - lo + 1))
    before = (s.scan < lo) & (np.abs(s.resid) >= tol)
    after = (s.scan > hi) & (np.abs(s.resid) >= tol)
    out["off_line_before"] = [int(before.sum()), float(np.median(s.resid[before])) if before.any() else None]
    out["off_line_after"] = [int(after.sum()), float(np.median(s.resid[after])) if after.any() else None]
    # rows inside the kept span that were dropped: why
    inside = (s.scan >= lo) & (s.scan <= hi) & ~k
    lost_runs = 0  # a separate run lies on the line, but the brightest run is elsewhere
    for i in np.flatnonzero(inside):
        for a, b in s.runs[i]:
            if a <= s.pos[i] < b:
                continue
            cu = (a + b - 1) / 2.0
            if abs(np.array([cu, s.scan[i]]) @ s.line[0] - s.line[1]) < tol + (b - a) / 2:
                lost_runs += 1
                break
    covered = set(s.scan.tolist())
    out["dropped_inside_span"] = {
        "no_peak": int(sum(1 for r in range(lo, hi + 1) if r not in covered)),
        "off_line": int(inside.sum()),
        "brighter_run_elsewhere": lost_runs,
    }
    return out


# =========================================================================================
# the report


def summarise(ds: DataSet, folds: List[Fold]) -> Dict:
    res: Dict = {"dataset": ds.name, "methods": {}}
    for m in ("PARK", "SHAH"):
        ch = [f.chain[m] for f in folds if f.chain]
        ls = np.concatenate([f.laser[m] for f in folds if f.laser])
        res["methods"][m] = {
            "chain_median_px": float(np.median([c[0] for c in ch])),
            "chain_median_mm": float(np.median([c[1] for c in ch])),
            "laser_median_abs_mm": float(np.median(np.abs(ls))),
            "laser_p95_abs_mm": float(np.percentile(np.abs(ls), 95)),
            "laser_median_signed_mm": float(np.median(ls)),
            "laser_points": int(len(ls)),
        }
    best = min(("PARK", "SHAH"), key=lambda m: res["methods"][m]["chain_median_px"])
    res["chosen"] = best
    return res


def fmt(x, nd=2):
    return "-" if x is None else f"{x:.{nd}f}"


def run(name: str, tol: float, model: Optional[str]) -> Dict:
    ds = load(name)
    # out/ holds the figures of the default settings only (rig's model, RANSAC_TOL_PX)
    write = model is None and tol == RANSAC_TOL_PX
    model = model or ds.rig["camera"].get("distortion_model", "radial1")
    direction = ds.rig.get("stripe", {}).get("direction", "cols")
    print(f"\n=== {name}: {len(ds.views)} views, board {ds.rig['board']['rows']} x "
          f"{ds.rig['board']['cols']} inner corners, distortion {model}, stripe {direction}, "
          f"RANSAC tol {tol} px")
    for v in ds.views:
        v.stripe = plain_extract(v.gray, direction, tol)

    # --- the full-data calibration (a sanity check of the recipe) ---
    full = calibrate(ds, ds.with_board(), model)
    fu, fv, u0, v0 = full.K[0, 0], full.K[1, 1], full.K[0, 2], full.K[1, 2]
    print(f"all views: calibrateCamera RMS {full.rms_px:.3f} px, fu {fu:.1f} fv {fv:.1f} "
          f"u0 {u0:.1f} v0 {v0:.1f} k1 {full.dist[0]:+.4f} k2 {full.dist[1]:+.4f}")
    n, d = full.plane
    print(f"laser plane (cam): n = [{n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f}], d = {d:.2f} mm, "
          f"TLS RMS {full.plane_rms_mm:.3f} mm over {full.plane_points} points")
    for m in ("PARK", "SHAH"):
        X = full.X[m]
        rv = cv2.Rodrigues(X[:3, :3])[0].ravel()
        print(f"  {m}: hand_cam rotvec [{rv[0]:+.4f}, {rv[1]:+.4f}, {rv[2]:+.4f}] "
              f"t [{X[0, 3]:.1f}, {X[1, 3]:.1f}, {X[2, 3]:.1f}] mm")
    dX = inv(full.X["PARK"]) @ full.X["SHAH"]
    print(f"  PARK vs SHAH hand-eye: {rot_angle_deg(dX[:3, :3]):.3f} deg, {np.linalg.norm(dX[:3, 3]):.2f} mm")

    # --- leave one view out ---
    folds = leave_one_out(ds, model)
    res = summarise(ds, folds)
    best = res["chosen"]
    print("\nper view, held out (the fold without the view): chain error px (PARK, SHAH) and mm "
          f"({best}); laser->board |d| median and p95 (PARK, SHAH); for {best} the signed median "
          "of d (the fold's offset: how far the predicted board plane is off along its normal) "
          "and the RMS of d about that median (the spread along the line)")
    print(f"{'row':>3} {'image':<22} {'board':<34} {'kept':>4} {'chPARK':>6} {'chSHAH':>6} {'chmm':>5} "
          f"{'lbPARK':>6} {'p95':>5} {'lbSHAH':>6} {'p95':>5} {'offset':>6} {'spread':>6}")
    for f in folds:
        v = f.held
        cp = f.chain.get("PARK", (None, None))
        cs = f.chain.get("SHAH", (None, None))
        cb = f.chain.get(best, (None, None))
        lp, lsh, lb = f.laser.get("PARK"), f.laser.get("SHAH"), f.laser.get(best)

        def q(x, p):
            return None if x is None else float(np.percentile(np.abs(x), p))

        off = None if lb is None else float(np.median(lb))
        spread = None if lb is None else float(np.sqrt(np.mean((lb - off) ** 2)))
        print(f"{v.row:>3} {v.image:<22} {v.corner_note:<34} {int(v.stripe.keep.sum()):>4} "
              f"{fmt(cp[0]):>6} {fmt(cs[0]):>6} {fmt(cb[1]):>5} {fmt(q(lp, 50)):>6} {fmt(q(lp, 95)):>5} "
              f"{fmt(q(lsh, 50)):>6} {fmt(q(lsh, 95)):>5} {fmt(off):>6} {fmt(spread):>6}")
    kept = [int(v.stripe.keep.sum()) for v in ds.views]
    res["plain_points_per_view"] = kept
    res["ransac_tol_px"] = tol
    res["distortion_model"] = model
    print(f"\nplain points per view: min {min(kept)}, max {max(kept)}, total {sum(kept)}")
    for m in ("PARK", "SHAH"):
        r = res["methods"][m]
        print(f"{m}: held-out chain median {r['chain_median_px']:.2f} px ({r['chain_median_mm']:.2f} mm); "
              f"held-out laser->board median {r['laser_median_abs_mm']:.3f} mm, p95 {r['laser_p95_abs_mm']:.3f} mm "
              f"(signed median {r['laser_median_signed_mm']:+.3f} mm, {r['laser_points']} points)")
    print(f"chosen by the held-out chain error: {res['chosen']}")

    # --- phenomena ---
    print("\nthe line, per view (kept rows): saturated share of run pixels, rows with a "
          "saturated pixel, width above half max p5/50/95, saturated plateau p5/50/95, base width above 10 %% of the max p5/50/95, "
          "rows with a second run (>= %d px / >= %d px wide, of all rows with a peak), jitter "
          "about a quadratic and row to row, bow of the kept span (raw; undistorted with the "
          "all-views camera), kept span, off-line rows before/after "
          "the span (count, median offset px)" % (MIN_RUN_PX, WIDE_RUN_PX))
    res["phenomena"] = []
    for v in ds.views:
        p = phenomena(v.stripe, tol, full.K, full.dist)
        p["row"] = v.row
        res["phenomena"].append(p)
        if not p["kept"]:
            print(f"{v.row:>3} no line")
            continue
        w, pl, bs = p["width_px_p5_50_95"], p["plateau_px_p5_50_95"], p["base_px_p5_50_95"]
        ob, oa = p["off_line_before"], p["off_line_after"]
        dr = p["dropped_inside_span"]
        print(f"{v.row:>3} sat {p['saturated_share']:.2f} rows_sat {p['rows_with_saturation']:.2f} "
              f"width {w[0]:.0f}/{w[1]:.0f}/{w[2]:.0f} plateau {pl[0]:.0f}/{pl[1]:.0f}/{pl[2]:.0f} "
              f"base {bs[0]:.0f}/{bs[1]:.0f}/{bs[2]:.0f} "
              f"2runs {p['rows_two_runs']}/{p['rows_two_runs_wide']} (|off| {fmt(p['second_run_offset_px_median_abs'], 0)}) "
              f"jitter {p['jitter_rms_px']:.2f} r2r {p['jitter_row_to_row_px']:.2f} "
              f"bow {p['bow_px']:.2f} (undist {p['bow_undistorted_px']:.2f}) span {p['kept_span'][0]}-{p['kept_span'][1]} "
              f"fill {p['kept_fill']:.2f} before {ob[0]} ({fmt(ob[1], 1)}) after {oa[0]} ({fmt(oa[1], 1)}) "
              f"dropped {dr['off_line']} (brighter run elsewhere {dr['brighter_run_elsewhere']}), no peak {dr['no_peak']}")

    # --- the plain points for the engineers ---
    if not write:
        print("\nout/ not written (non-default --tol or --model)")
        return res
    out = {
        "dataset": name,
        "extractor": {
            "tophat_width_px": TOPHAT_WIDTH, "min_peak": MIN_PEAK, "rel_threshold": REL_THRESHOLD,
            "ransac_tol_px": tol, "direction": direction,
        },
        "views": [
            {"row": v.row, "image": v.image,
             "points": [[round(float(u), 3), round(float(w), 3)] for u, w in v.stripe.uv()]}
            for v in ds.views
        ],
    }
    (HERE / "out").mkdir(exist_ok=True)
    path = HERE / "out" / f"{name}_plain_points.json"
    path.write_text(json.dumps(out, separators=(",", ":")) + "\n")
    (HERE / "out" / f"{name}_summary.json").write_text(json.dumps(res, indent=1) + "\n")
    print(f"\nwrote {path.relative_to(HERE)} and out/{name}_summary.json")
    return res


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dataset", action="append", choices=DATASETS, help="default: both")
    ap.add_argument("--tol", type=float, default=RANSAC_TOL_PX, help="RANSAC inlier band, px")
    ap.add_argument("--model", choices=("radial1", "radial2", "opencv5"), help="default: rig.json's")
    ap.add_argument("--realdata", type=Path, default=REALDATA, help="folder holding the data sets")
    a = ap.parse_args(argv)
    set_realdata(a.realdata)
    for name in a.dataset or DATASETS:
        run(name, a.tol, a.model)
    return 0


if __name__ == "__main__":
    sys.exit(main())
