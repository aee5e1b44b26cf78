"""Target detection on REAL photographs (issue 10, acceptance 1 and 2), against OpenCV's
detectors on the same images.

The data sets live in ../shared/realdata (never copied into the repository); the
tests are skipped when that folder is absent. Each data set's rig.json gives the board.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import stripecal

REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"
F64 = npt.NDArray[np.float64]


def dataset(name: str) -> Tuple[Path, Dict[str, Any], List[Path]]:
    root = REALDATA / name
    if not (root / "rig.json").exists():
        pytest.skip(f"real data set {root} not present")
    rig = json.loads((root / "rig.json").read_text())
    with open(root / "views.csv", newline="") as f:
        images = [root / row["board_image"] for row in csv.DictReader(f)]
    return root, rig, images


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


def lattice_map_consistent(ours: npt.NDArray[np.int64], theirs: npt.NDArray[np.int64]) -> bool:
    """Whether (row, col) -> (row', col') is one of the 8 lattice symmetries plus a
    shift, the same for every point."""
    for perm in (False, True):
        for sr in (1, -1):
            for sc in (1, -1):
                a = ours[:, ::-1] if perm else ours
                m = a * np.array([sr, sc])
                shift = theirs - m
                if np.all(shift == shift[0]):
                    return True
    return False


def test_rosi_circle_grid_against_opencv() -> None:
    """Acceptance 1: the ROS-Industrial 10 x 10 dot grid (one big origin dot, the only
    marker), 15 real 640 x 480 colour photographs: every view detected and indexed from
    the big dot; the centres agree with cv2.findCirclesGrid's (matched per circle) within
    0.1 px median."""
    cv2 = pytest.importorskip("cv2")
    root, rig, images = dataset("rosi_10x10")
    board = board_of(rig)
    assert len(images) == 15
    medians: List[float] = []
    all_d: List[F64] = []
    for p in images:
        bgr = cv2.imread(str(p))
        rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        det = stripecal.detect_target(rgb, board)  # RGB in: BT.601 gray inside
        assert det.alternatives == [], p.name
        idx, pts = det.indices, det.points
        assert len(idx) >= 95, f"{p.name}: {len(idx)} circles"
        # independent check of the origin: the largest dark blob near the grid (OpenCV's
        # own connected components) is the big dot, and we call the circle there (0, 0)
        gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
        _, bw = cv2.threshold(gray, 0, 255, cv2.THRESH_BINARY_INV + cv2.THRESH_OTSU)
        n, _, stats, cents = cv2.connectedComponentsWithStats(bw)
        pitch = float(np.median(np.linalg.norm(np.diff(pts[:10], axis=0), axis=1)))
        near = [
            k
            for k in range(1, n)
            if np.min(np.linalg.norm(pts - cents[k], axis=1)) < 0.6 * pitch
            and stats[k, cv2.CC_STAT_AREA] < 4 * pitch * pitch
        ]
        big = max(near, key=lambda k: stats[k, cv2.CC_STAT_AREA])
        nearest = int(np.argmin(np.linalg.norm(pts - cents[big], axis=1)))
        if tuple(idx[nearest]) == (0, 0):
            pass
        else:
            # the big dot may be cut by the image border and left unmeasured: then (0, 0)
            # is absent and the big dot's blob sits next to (0, 1) / (1, 0)
            assert not any((r, c) == (0, 0) for r, c in idx), p.name
            assert tuple(idx[nearest]) in {(0, 1), (1, 0), (1, 1)}, (p.name, idx[nearest])
        ok, c = cv2.findCirclesGrid(gray, (board.cols, board.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
        assert ok, f"{p.name}: OpenCV found no grid"
        theirs = np.asarray(c, np.float64).reshape(-1, 2)
        dist = np.linalg.norm(pts[:, None, :] - theirs[None, :, :], axis=2)
        k = dist.argmin(axis=1)
        d = dist[np.arange(len(pts)), k]
        assert d.max() < 1.0, f"{p.name}: a circle of ours is not one of OpenCV's"
        assert len(set(k.tolist())) == len(k), f"{p.name}: two of ours on one of OpenCV's"
        # the same lattice: our (row, col) maps to OpenCV's (index // cols, index % cols) by
        # one lattice symmetry for every circle
        their_rc = np.stack([k // board.cols, k % board.cols], axis=1)
        assert lattice_map_consistent(idx, their_rc), p.name
        medians.append(float(np.median(d)))
        all_d.append(d)
    allv = np.concatenate(all_d)
    print(
        f"\nrosi_10x10: 15/15 views, {allv.size} circles; distance to cv2.findCirclesGrid: "
        f"median {np.median(allv):.4f} px, per-view medians {min(medians):.4f}..{max(medians):.4f} px, "
        f"max {allv.max():.4f} px"
    )
    assert np.median(allv) <= 0.1
    assert max(medians) <= 0.1


def test_visp_chessboard_against_opencv() -> None:
    """Acceptance 2: the ViSP Franka set (chessboard 9 x 6 inner corners, 23.6 mm, 8
    real 640 x 480 views): every view detected with all 54 corners, indexed per the
    contract (right-handed, the square outside corner (0, 0) dark).

    Against OpenCV on the same images: the corners agree with cv2.cornerSubPix (after
    cv2.findChessboardCorners) within 0.1 px median; cv2.findChessboardCornersSB's
    corners are printed, not asserted: they move by up to 0.35 px between its own flag
    settings and sit 0.2-0.6 px from both ours and cornerSubPix (BENCHMARKS.md, "Vision:
    targets"). Which set is more accurate is measured instead: the same 8-view camera
    calibration (cv2.calibrateCamera, k1, k2) has a lower reprojection RMS with ours than
    with either OpenCV detector's."""
    cv2 = pytest.importorskip("cv2")
    root, rig, images = dataset("visp_franka")
    board = board_of(rig)
    assert len(images) == 8 and (board.rows, board.cols) == (6, 9)
    sb_flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    sets: Dict[str, List[F64]] = {"stripecal": [], "cornerSubPix": [], "findChessboardCornersSB": []}
    d_sub: List[F64] = []
    d_sb: List[F64] = []
    indices = None
    for p in images:
        gray = cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)
        det = stripecal.detect_target(gray, board)
        assert len(det) == 54 and det.alternatives == [], p.name
        if indices is None:
            indices = det.indices
        assert np.array_equal(det.indices, indices)
        pts = det.points
        # the contract's orientation: col increases along +x, row along +y, right-handed
        # (u right, v down), and the square outside corner (0, 0) is dark
        p00, p01, p10, p11 = (pts[list(map(tuple, det.indices)).index(rc)] for rc in [(0, 0), (0, 1), (1, 0), (1, 1)])
        dx, dy = p01 - p00, p10 - p00
        assert dx[0] * dy[1] - dx[1] * dy[0] > 0, p.name
        dark = p00 - 0.5 * (p11 - p00)  # square (-1, -1): dark
        light = p00 + 0.5 * dx - 0.5 * dy  # square (0, -1): light
        assert int(gray[int(round(dark[1])), int(round(dark[0]))]) < int(gray[int(round(light[1])), int(round(light[0]))]) - 30, p.name

        def ordered(q: F64) -> F64:
            d = np.linalg.norm(pts[:, None, :] - q[None, :, :], axis=2)
            k = d.argmin(axis=1)
            assert len(set(k.tolist())) == len(k) and d[np.arange(len(k)), k].max() < 3.0, p.name
            return np.asarray(q[k], np.float64)

        ok, c = cv2.findChessboardCorners(gray, (board.cols, board.rows))
        assert ok, p.name
        sub = ordered(cv2.cornerSubPix(gray, c, (5, 5), (-1, -1), crit).reshape(-1, 2).astype(np.float64))
        ok, c = cv2.findChessboardCornersSB(gray, (board.cols, board.rows), flags=sb_flags)
        assert ok, p.name
        sb = ordered(np.asarray(c, np.float64).reshape(-1, 2))
        sets["stripecal"].append(pts)
        sets["cornerSubPix"].append(sub)
        sets["findChessboardCornersSB"].append(sb)
        d_sub.append(np.linalg.norm(pts - sub, axis=1))
        d_sb.append(np.linalg.norm(pts - sb, axis=1))
    assert indices is not None
    obj = np.array([[c * board.pitch_mm, r * board.pitch_mm, 0.0] for r, c in indices], np.float32)
    rms = {}
    for name, pts_list in sets.items():
        rms[name], *_ = cv2.calibrateCamera(
            [obj] * len(pts_list),
            [q.astype(np.float32) for q in pts_list],
            (640, 480),
            None,
            None,
            flags=cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST,
        )
    ds, db = np.concatenate(d_sub), np.concatenate(d_sb)
    print(
        f"\nvisp_franka: 8/8 views, 432 corners; distance to cv2.cornerSubPix median {np.median(ds):.4f} px "
        f"(per view {min(map(np.median, d_sub)):.4f}..{max(map(np.median, d_sub)):.4f}); to "
        f"cv2.findChessboardCornersSB median {np.median(db):.4f} px (per view "
        f"{min(map(np.median, d_sb)):.4f}..{max(map(np.median, d_sb)):.4f}); calibrateCamera RMS: "
        + ", ".join(f"{k} {v:.4f} px" for k, v in rms.items())
    )
    assert np.median(ds) <= 0.1 and max(map(np.median, d_sub)) <= 0.1
    assert rms["stripecal"] <= rms["cornerSubPix"] and rms["stripecal"] <= rms["findChessboardCornersSB"]


def test_rosi_as_jpeg_and_bmp_files(tmp_path: Path) -> None:
    """The real photographs saved as JPEG (quality 90) and BMP and read back through
    stripecal.load_image: every view still detected and indexed; BMP is lossless (the
    same points as the PNG), JPEG moves the centres by its compression noise only."""
    cv2 = pytest.importorskip("cv2")
    root, rig, images = dataset("rosi_10x10")
    board = board_of(rig)
    shifts: List[F64] = []
    for p in images:
        ref = stripecal.detect_target(stripecal.load_image(str(p)), board)
        bgr = cv2.imread(str(p))
        for ext, params in ((".jpg", [cv2.IMWRITE_JPEG_QUALITY, 90]), (".bmp", [])):
            f = tmp_path / (p.stem + ext)
            assert cv2.imwrite(str(f), bgr, params)
            det = stripecal.detect_target(stripecal.load_image(str(f)), board)
            assert np.array_equal(det.indices, ref.indices), (p.name, ext)
            d = np.linalg.norm(det.points - ref.points, axis=1)
            if ext == ".bmp":
                assert d.max() < 1e-9, p.name
            else:
                shifts.append(d)
    s = np.concatenate(shifts)
    print(f"\nrosi_10x10 as JPEG q90: 15/15 views, centre shift against PNG median {np.median(s):.4f} px, max {s.max():.4f} px")
    assert np.median(s) < 0.05
