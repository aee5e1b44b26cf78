"""Issue 12, acceptance 1 and 2: `stripecal calibrate` on the real data sets (no laser,
poses as pose columns) succeeds end to end and prints the leave-one-view-out figure, and
its median held-out chain error is no worse than OpenCV's (cv2.calibrateCamera +
cv2.calibrateRobotWorldHandEye SHAH) on the same views, the same detected points and
the same held-out definition (tests/_opencv_loo.py says it in full).

- rosi_10x10: 10 x 10 dot grid, one marker; poses x_m,y_m,z_m + quaternion in ROS order
  (qx,qy,qz,qw) of T_base_flange; 15 views.
- visp_franka: chessboard 9 x 6 inner corners, 23.6 mm; poses x_m,y_m,z_m + rotation
  vector (rad) of T_base_ee; 8 views.

The data sets live in ../shared/realdata (never copied into the repository); the tests
are skipped when it is absent. `python -m pytest tests/test_realdata_loo.py -s` prints
OpenCV's per-view and median figures and, once calibrate writes them, ours beside them.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any, Callable, Dict, List

import numpy as np
import pytest
import stripecal

cv2 = pytest.importorskip("cv2")

import _opencv_loo as ocv  # noqa: E402  (tests/ is on sys.path under pytest)

REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"
SETS = ["rosi_10x10", "visp_franka"]


@pytest.fixture(scope="module")
def realset() -> Callable[[str], ocv.RealSet]:
    """Loads (detects, parses, labels) each data set once per module."""
    cache: Dict[str, ocv.RealSet] = {}

    def get(name: str) -> ocv.RealSet:
        root = REALDATA / name
        if not (root / "rig.json").exists():
            pytest.skip(f"real data set {root} not present")
        if name not in cache:
            cache[name] = ocv.load_set(root)
        return cache[name]

    return get


@pytest.fixture(scope="module")
def opencv_loo(realset: Callable[[str], ocv.RealSet]) -> Callable[[str], Dict[str, Any]]:
    """OpenCV's leave-one-out over all views of a set, once per module."""
    cache: Dict[str, Dict[str, Any]] = {}

    def get(name: str) -> Dict[str, Any]:
        if name not in cache:
            cache[name] = ocv.leave_one_out(realset(name))
        return cache[name]

    return get


def test_pose_parsing_by_hand() -> None:
    """The numpy pose parsers on known values: ROS quaternion order read by name, a
    rotation vector by Rodrigues (against cv2.Rodrigues), metres to millimetres."""
    # a quarter turn about z: (qx, qy, qz, qw) = (0, 0, sin 45, cos 45)
    h = float(np.sqrt(0.5))
    a = ocv.pose_of_row({"x_m": "0.1", "y_m": "-0.2", "z_m": "0.3", "qx": "0", "qy": "0", "qz": str(h), "qw": str(h)})
    assert np.allclose(a[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    assert np.allclose(a[:3, 3], [100.0, -200.0, 300.0])
    w = [0.3, -1.2, 2.5]
    b = ocv.pose_of_row({"x_m": "0", "y_m": "0", "z_m": "0", "rx_rad": "0.3", "ry_rad": "-1.2", "rz_rad": "2.5"})
    assert np.allclose(b[:3, :3], cv2.Rodrigues(np.array(w))[0], atol=1e-12)
    with pytest.raises(AssertionError):
        ocv.quat_to_matrix(1.0, 0.1, 0.0, 0.0)


@pytest.mark.parametrize("name", SETS)
def test_opencv_conventions_on_the_full_set(name: str, realset: Callable[[str], ocv.RealSet]) -> None:
    """Before trusting the OpenCV reference: on ALL views, (A_i X)^-1 Z with SHAH's X, Z
    (converted from base2world / gripper2cam) reproduces calibrateCamera's board poses to
    a degree or two and about a centimetre; SHAH's X agrees with cv2.calibrateHandEye
    (PARK), whose output cam2gripper IS T_hand_cam with no conversion; and a deliberately
    wrong reading of the rotations (the ROS quaternion taken positionally as w, x, y, z;
    the rotation vector's inverse) is far less consistent. Prints the plain (not held-out)
    reprojection RMS, the AX = ZB consistency and the board scale the robot implies."""
    s = realset(name)
    c = ocv.calibrate(s, s.views)
    cons = ocv.in_sample(s, c, s.views)
    scale, res_s, res_1 = ocv.implied_scale(s, c)
    pitch = s.rig["board"].get("pitch_mm", s.rig["board"].get("square_mm"))
    print(
        f"\n{name}: {len(s.views)} views, {sum(len(v.points) for v in s.views)} points; labelling: {s.labelling_note}\n"
        f"  cv2.calibrateCamera RMS {c.rms:.4f} px; fu {c.K[0, 0]:.2f} fv {c.K[1, 1]:.2f} u0 {c.K[0, 2]:.2f} "
        f"v0 {c.K[1, 2]:.2f} k1 {c.dist[0]:.4f} k2 {c.dist[1]:.4f}\n"
        f"  AX=ZB (SHAH, all views): board poses from the robot vs calibrateCamera's: rotation RMS "
        f"{cons['pose_rot_rms_deg']:.3f} deg (max {cons['pose_rot_max_deg']:.3f}), translation RMS "
        f"{cons['pose_trans_rms_mm']:.2f} mm (max {cons['pose_trans_max_mm']:.2f}); predicted reprojection RMS "
        f"{cons['predicted_rms_px']:.3f} px\n"
        f"  board scale the robot implies: {scale:.4f} (pitch {scale * pitch:.2f} mm for {pitch} mm); "
        f"translation residual {res_s:.2f} mm at that scale, {res_1:.2f} mm at 1"
    )
    assert c.rms < 0.5
    assert cons["pose_rot_rms_deg"] < 2.0 and cons["pose_trans_rms_mm"] < 15.0
    # cv2.calibrateHandEye takes gripper2base = T_base_hand and target2cam = T_cam_board
    # and returns cam2gripper = T_hand_cam: an independent check of the X conversion
    r, t = cv2.calibrateHandEye(
        [v.A[:3, :3] for v in s.views], [v.A[:3, 3] for v in s.views],
        [T[:3, :3] for T in c.T_cam_board], [T[:3, 3] for T in c.T_cam_board],
        method=cv2.CALIB_HAND_EYE_PARK,
    )
    x2 = ocv.make(np.asarray(r, np.float64), np.asarray(t, np.float64))
    assert ocv.angle_deg(x2[:3, :3].T @ c.X[:3, :3]) < 1.0
    assert np.linalg.norm(x2[:3, 3] - c.X[:3, 3]) < 20.0
    # the negative control: a wrong rotation convention breaks the consistency
    root = REALDATA / name
    with open(root / "views.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    wrong = []
    for v, row in zip(s.views, rows):
        if "qw" in row:
            rr = ocv.quat_to_matrix(*(float(row[k]) for k in ("qx", "qy", "qz", "qw")))
        else:
            rr = v.A[:3, :3].T
        wrong.append(ocv.make(rr, v.A[:3, 3]))
    xw, zw = ocv.robot_world_hand_eye(c.T_cam_board, wrong)
    bad = ocv.in_sample(s, dataclasses.replace(c, X=xw, Z=zw),
                        [dataclasses.replace(v, A=a) for v, a in zip(s.views, wrong)])
    assert bad["pose_trans_rms_mm"] > 5 * cons["pose_trans_rms_mm"]


def test_chessboard_labelling_from_the_robot(realset: Callable[[str], ocv.RealSet]) -> None:
    """visp_franka: the 9 x 6 corner grid looks the same after a half turn. The detector
    decides by the colours (rows + cols odd, so no alternatives); the robot, asked
    independently (every combination of half turns over views 2..8 against AX = ZB), picks
    the same labelling in every view, by a wide margin."""
    s = realset("visp_franka")
    assert all(len(v.candidates) == 2 for v in s.views)
    (best, combo), (nxt, _) = s.labelling_scores[0], s.labelling_scores[1]
    assert combo == (0,) * len(s.views), s.labelling_note
    assert nxt > 10 * best, s.labelling_note


@pytest.mark.parametrize("name", SETS)
def test_opencv_leave_one_out(name: str, realset: Callable[[str], ocv.RealSet],
                              opencv_loo: Callable[[str], Dict[str, Any]]) -> None:
    """OpenCV's held-out figures, printed per view (the reference the CLI is held to)."""
    s = realset(name)
    r = opencv_loo(name)
    print(f"\n{name}: OpenCV leave-one-out (calibrateCamera + SHAH), per view:")
    for o in r["views"]:
        print(f"  view {o['view']:2d}  {o['points']:3d} pts  board_rms_px {o['board_rms_px']:7.3f}  "
              f"board_rms_mm {o['board_rms_mm']:7.3f}")
    print(f"  median board_rms_px {r['median_board_rms_px']:.3f}  median board_rms_mm {r['median_board_rms_mm']:.3f}")
    assert len(r["views"]) == len(s.views)
    assert all(np.isfinite(o["board_rms_px"]) and np.isfinite(o["board_rms_mm"]) for o in r["views"])
    # robot-limited: a few px / mm, never a convention slip (hundreds)
    assert r["median_board_rms_px"] < 20.0 and r["median_board_rms_mm"] < 20.0


LOO_PHRASE = re.compile(r"leave[- ]one[- ](view[- ])?out", re.IGNORECASE)


# visp_franka: the robot motions imply a board about 11 % larger than rig.json's 23.6 mm
# squares (the board-scale check: 1.133 +- 0.010). Since issue 38 (DECISIONS 5) a scale
# more than 5 honest sigmas off fails the calibration, so the set is calibrated with
# --estimate-board-scale, as a user would after that failure. (Before, with the scale held,
# ours was 5 % worse than OpenCV in mm on the board and this set was a strict xfail.)
# rosi_10x10's printed pitch is in doubt as well (realdata/README.md: 25.4 mm in the
# source, 24.8-25.0 implied by the robot), and issue 38 has its figures taken with the
# scale free too: with it held, the 0.84 % the robot implies goes into the per-view pose
# corrections, which a held-out view is predicted without (1.39 px against 1.12 free).
CLI_SETS = ["rosi_10x10", "visp_franka"]
CLI_OPTIONS = {"rosi_10x10": ["--estimate-board-scale"], "visp_franka": ["--estimate-board-scale"]}
# Issue 38, acceptance 2: the held-out chain error (median px) within 10 % of the default
# before the robot-pose noise model (1.15 and 6.47 px), as well as no worse than OpenCV's.
BEFORE_POSE_NOISE_PX = {"rosi_10x10": 1.15, "visp_franka": 6.47}


@pytest.mark.parametrize("name", CLI_SETS)
def test_calibrate_cli_leave_one_out_no_worse_than_opencv(
    name: str, tmp_path: Path, realset: Callable[[str], ocv.RealSet], opencv_loo: Callable[[str], Dict[str, Any]]
) -> None:
    """Acceptance 1 (rosi_10x10) and 2 (visp_franka): `stripecal calibrate SET -o
    cal.json` exits 0 without a laser, prints the leave-one-out figure and writes
    `leave_one_out`; its medians over the views it used are no worse than OpenCV's on
    the same views."""
    s = realset(name)
    out = tmp_path / "cal.json"
    proc = subprocess.run(
        [sys.executable, "-m", "stripecal", "calibrate", str(REALDATA / name), "-o", str(out)] + CLI_OPTIONS[name],
        capture_output=True, text=True, timeout=900,
    )
    print(f"\n{name}: stripecal calibrate exit {proc.returncode}\n{proc.stdout}{proc.stderr}")
    assert proc.returncode == 0, proc.stderr
    assert LOO_PHRASE.search(proc.stdout), "calibrate did not print the leave-one-out figure"
    cal = json.loads(out.read_text())
    assert cal["laser_plane"] is None  # no laser images: DATASET.md "The calibration result"
    loo = cal["leave_one_out"]
    views: List[Dict[str, Any]] = loo["views"]
    rows = [int(v["view"]) for v in views]
    assert len(set(rows)) == len(rows) and set(rows) <= {v.row for v in s.views}
    assert len(rows) >= 3
    for v in views:
        assert v["stripe_rms_mm"] is None
        assert 0 < v["points"] <= len(s.views[v["view"]].points)
    assert loo["median_stripe_rms_mm"] is None
    assert loo["median_board_rms_px"] == pytest.approx(float(np.median([v["board_rms_px"] for v in views])), rel=1e-6)
    assert loo["median_board_rms_mm"] == pytest.approx(float(np.median([v["board_rms_mm"] for v in views])), rel=1e-6)
    # OpenCV on the same views: the full run when ours used them all, else rerun on ours'
    ref = opencv_loo(name) if sorted(rows) == [v.row for v in s.views] else ocv.leave_one_out(s, rows)
    theirs = {o["view"]: o for o in ref["views"]}
    print(f"{name}: leave-one-out, ours vs OpenCV (calibrateCamera + SHAH) on the same {len(rows)} views")
    for v in views:
        o = theirs[v["view"]]
        print(f"  view {v['view']:2d}  px {v['board_rms_px']:7.3f} vs {o['board_rms_px']:7.3f}   "
              f"mm {v['board_rms_mm']:7.3f} vs {o['board_rms_mm']:7.3f}")
    print(f"  median px {loo['median_board_rms_px']:.3f} vs {ref['median_board_rms_px']:.3f}   "
          f"median mm {loo['median_board_rms_mm']:.3f} vs {ref['median_board_rms_mm']:.3f}")
    assert loo["median_board_rms_px"] <= ref["median_board_rms_px"]
    assert loo["median_board_rms_mm"] <= ref["median_board_rms_mm"]
    assert loo["median_board_rms_px"] <= 1.1 * BEFORE_POSE_NOISE_PX[name]


def _with_board(root: Path, ds: Path, board: Dict[str, Any]) -> Path:
    """A copy of the real set `root` at `ds` whose rig.json's board has the keys `board`
    changed (views.csv copied, the images linked, not copied)."""
    ds.mkdir()
    rig = json.loads((root / "rig.json").read_text())
    rig["board"].update(board)
    (ds / "rig.json").write_text(json.dumps(rig))
    (ds / "views.csv").write_text((root / "views.csv").read_text())
    (ds / "images").symlink_to(root / "images", target_is_directory=True)
    return ds


def test_board_scale_check_on_rosi_reports_the_scale_and_flags_the_sources_pitch(tmp_path: Path) -> None:
    """Issue 12, item 5 (DECISIONS 7): rosi_10x10's rig.json carries the corrected 25.0 mm
    pitch: the check reports a scale within 1 % of 1 with its sigma and stays silent. The
    source's own 25.4 mm is flagged: since issue 38 (DECISIONS 5, more than 5 honest sigmas
    off) the calibration fails, naming the implied pitch and --estimate-board-scale; with
    that option it is calibrated and the scale reported."""
    root = REALDATA / "rosi_10x10"
    if not (root / "rig.json").exists():
        pytest.skip(f"real data set {root} not present")
    cal = stripecal.calibrate(root, leave_one_out=False)
    bs = cal.board_scale
    assert bs is not None
    print(f"\nrosi_10x10 25.0 mm: scale {bs['scale']:.5f} +- {bs['sigma']:.5f} -> {bs['implied_mm']:.3f} mm")
    assert abs(bs["scale"] - 1.0) < 0.01 and 0.0 < bs["sigma"] < 0.01
    assert not bs["disagrees"]
    assert not any("board scale" in w for w in cal.extra.get("warnings", []))
    # The source's config: 25.4 mm (the same images and poses, linked, not copied).
    ds = _with_board(root, tmp_path / "rosi_254", {"pitch_mm": 25.4})
    with pytest.raises(stripecal.CalibrationQualityError) as e:
        stripecal.calibrate(ds, leave_one_out=False)
    failed = {c["name"]: c["message"] for c in e.value.checks}
    print(f"rosi_10x10 25.4 mm: {failed}")
    assert list(failed) == ["board_scale"]
    assert "--estimate-board-scale" in failed["board_scale"] and "25.400 mm implies" in failed["board_scale"]
    held = e.value.calibration
    assert held is not None and held.board_scale is not None
    bs2 = held.board_scale
    assert bs2["disagrees"]
    assert bs2["implied_mm"] == pytest.approx(bs["implied_mm"], abs=0.1)
    cal3 = stripecal.calibrate(ds, leave_one_out=False, estimate_board_scale=True)
    bs3 = cal3.board_scale
    assert bs3 is not None and bs3["estimated"]
    print(f"rosi_10x10 25.4 mm, --estimate-board-scale: scale {bs3['scale']:.5f} +- {bs3['sigma']:.5f}")
    assert bs3["implied_mm"] == pytest.approx(bs["implied_mm"], abs=0.15)


@pytest.mark.parametrize("printed", [0.8, 1.1])
def test_a_board_printed_at_another_scale_is_refused_naming_the_implied_size(tmp_path: Path, printed: float) -> None:
    """Issue 39, fault 5: rosi_10x10 with rig.json's board sizes as if printed at 1/0.8 or
    1/1.1 of the print (a print at 0.8x or 1.1x): refused, naming the implied size. At 1.1x
    the board_scale gate fails naming the implied pitch and --estimate-board-scale; at 0.8x
    the views' translations already disagree by 15 % and the pairing fails, naming the
    scale the robot implies (roughly)."""
    root = REALDATA / "rosi_10x10"
    if not (root / "rig.json").exists():
        pytest.skip(f"real data set {root} not present")
    board = json.loads((root / "rig.json").read_text())["board"]
    ds = _with_board(root, tmp_path / f"rosi_x{printed}",
                     {k: board[k] / printed for k in ["pitch_mm", "circle_diameter_mm", "marker_diameter_mm"]})
    with pytest.raises(stripecal.CalibrationQualityError) as e:
        stripecal.calibrate(ds, leave_one_out=False)
    failed = {c["name"]: c["message"] for c in e.value.checks}
    print(f"\nrosi_10x10 printed at {printed}x: {failed}")
    if printed > 1.0:
        assert list(failed) == ["board_scale"]
        implied = float(re.search(r"implies ([0-9.]+) mm", failed["board_scale"]).group(1))  # type: ignore[union-attr]
        # the print's pitch as the robot sees it: 0.9916 x 25.0 = 24.79 mm (the test above)
        assert implied == pytest.approx(24.79, abs=0.25)
        assert "--estimate-board-scale" in failed["board_scale"]
    else:
        assert list(failed) == ["pairing"]
        # a rough figure (AX = ZB with the scale free; the board's translations vary
        # little across the views): 0.76 for the print's 0.8 x 0.9916 = 0.79
        k = float(re.search(r"imply a board about ([0-9.]+) times", failed["pairing"]).group(1))  # type: ignore[union-attr]
        assert k == pytest.approx(printed, rel=0.06)
