"""stripecal.detect_target (issue 10): every target kind through one call, against the
twin's truth; colour input; bad input (no board, two boards, a board of the wrong size
in rig.json) as typed errors, at the call and through the calibration pipeline."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict

import numpy as np
import numpy.typing as npt
import pytest

import stripecal
import stripecal.sim as sim

F64 = npt.NDArray[np.float64]
KINDS = {"circles": "hp3-paper", "asymmetric_circles": "hp3-asymmetric", "chessboard": "hp3-chessboard"}


@pytest.fixture(scope="module")
def views() -> Dict[str, Dict[str, Any]]:
    """One board image (pose 0) of each kind's preset, with the twin's board."""
    out = {}
    for kind, name in KINDS.items():
        twin = sim.Twin(sim.preset(name, seed=3))
        v = twin.render_view(twin.calibration_poses()[0]["q_deg"], 0)
        v["board"] = twin.board
        out[kind] = v
    return out


def errors(det: stripecal.TargetDetection, view: Dict[str, Any]) -> F64:
    truth = {(int(r), int(c)): p for (r, c), p in zip(view["target_indices"], view["target_points"])}
    return np.array([np.hypot(*(p - truth[(int(r), int(c))])) for (r, c), p in zip(det.indices, det.points)])


@pytest.mark.parametrize("kind", list(KINDS))
def test_every_kind_against_truth(views: Dict[str, Dict[str, Any]], kind: str) -> None:
    v = views[kind]
    board = v["board"]
    assert board.kind == kind
    det = stripecal.detect_target(v["board_image"], board)
    assert det.kind == kind and len(det) == len(board) and det.alternatives == []
    assert det.indices.dtype == np.int64 and det.points.dtype == np.float64 and det.flags.dtype == np.uint8
    assert [tuple(x) for x in det.indices] == [tuple(x) for x in board.indices()]
    e = errors(det, v)
    print(f"\n{kind}: {len(e)} points, RMS {np.sqrt(np.mean(e**2)):.4f} px, max {e.max():.4f} px")
    assert np.sqrt(np.mean(e**2)) < 0.02 and e.max() < 0.08
    # markers flagged (circles only)
    marked = {tuple(i) for i, f in zip(det.indices, det.flags) if f & stripecal.TargetDetection.FLAG_MARKER}
    assert marked == set(board.markers)
    # colour input: BT.601 of equal channels is the gray image itself
    rgb = np.repeat(v["board_image"][:, :, None], 3, axis=2)
    det2 = stripecal.detect_target(rgb, board)
    assert np.array_equal(det2.indices, det.indices) and np.allclose(det2.points, det.points)


def test_symmetric_board_reports_its_alternatives(views: Dict[str, Dict[str, Any]]) -> None:
    v = views["circles"]
    b = v["board"]
    bare = stripecal.Board(b.rows, b.cols, b.pitch_mm, b.circle_diameter_mm, markers=[])
    assert bare.symmetries() == [(2, (b.cols - 1, b.rows - 1))]
    det = stripecal.detect_target(v["board_image"], bare)
    assert det.alternatives == bare.symmetries()
    # one of the two labellings is the truth
    truth = {tuple(x) for x in v["target_indices"]}
    e0 = errors(det, v)
    flipped = det.relabel(0)
    assert {tuple(x) for x in flipped} == truth
    assert e0.max() < 0.1 or all(
        np.hypot(*(p - v["target_points"][list(map(tuple, v["target_indices"])).index(tuple(i))])) < 0.1
        for i, p in zip(flipped, det.points)
    )
    with pytest.raises(IndexError):
        det.relabel(1)


@pytest.mark.parametrize("kind", list(KINDS))
def test_bad_input_is_a_typed_error(views: Dict[str, Dict[str, Any]], kind: str) -> None:
    """Acceptance 6: no board, two boards, a board of the wrong size: DetectionError with
    the reason; never a panic."""
    v = views[kind]
    img, board = v["board_image"], v["board"]
    # no board: a flat, noisy plate
    rng = np.random.default_rng(4)
    flat = rng.normal(150, 2, img.shape).clip(0, 255).astype(np.uint8)
    with pytest.raises(stripecal.DetectionError):
        stripecal.detect_target(flat, board)
    # two boards side by side
    two = np.concatenate([img, img[:, ::-1][::-1]], axis=1)
    with pytest.raises(stripecal.DetectionError, match="two boards"):
        stripecal.detect_target(two, board)
    # the wrong size in rig.json: one row more, one column fewer
    for dr, dc in [(1, 0), (0, -1)]:
        if kind == "chessboard":
            wrong = stripecal.Board.chessboard(board.rows + dr, board.cols + dc, board.pitch_mm)
        elif kind == "asymmetric_circles":
            wrong = stripecal.Board.asymmetric_circles(
                board.rows + dr, board.cols + dc, board.pitch_mm, board.circle_diameter_mm
            )
        else:
            wrong = stripecal.Board(
                board.rows + dr, board.cols + dc, board.pitch_mm, board.circle_diameter_mm, board.marker_diameter_mm
            )
        with pytest.raises(stripecal.DetectionError) as info:
            stripecal.detect_target(img, wrong)
        print(f"\n{kind} {wrong.rows} x {wrong.cols}: {info.value}")


def test_wrong_size_through_the_pipeline(tmp_path: Path) -> None:
    """A dataset whose rig.json has the wrong board size: calibrate raises a
    DetectionError that names the views and the reason."""
    twin = sim.Twin(sim.preset("hp3-paper", seed=2, poses={"count": 4}, scan={"enabled": False}))
    twin.write(str(tmp_path))
    rig_path = tmp_path / "calib" / "rig.json"
    rig = json.loads(rig_path.read_text())
    rig["board"]["cols"] -= 1
    rig_path.write_text(json.dumps(rig))
    with pytest.raises(stripecal.DetectionError) as info:
        stripecal.calibrate(str(tmp_path / "calib"))
    msg = str(info.value)
    assert "0 of 4 views" in msg and "view 0 (views.csv line 2)" in msg and "larger than the board" in msg, msg
