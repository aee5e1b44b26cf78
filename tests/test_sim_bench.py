"""The twin's bench mode (issue 17) through ``stripecal.sim``: a bench dataset (fixed
sensor, board placed by hand, one bent view, a floor) and a fixed-sensor conveyor scan,
rendered once per module, checked against the twin's truth."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Dict, List, Tuple

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim

VIEWS = 5
BENCH: Dict[str, Any] = {
    "enabled": True,
    "views": VIEWS,
    "partial_views": 1,
    "bow": {"views": [1], "sag_mm": 1.0, "axis_deg": 90.0},
    "floor": {"enabled": True},
    "scan": {"enabled": True, "step_mm": 4.0},
}


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Tuple[sim.Twin, Path, Dict[str, Any]]:
    out = tmp_path_factory.mktemp("bench")
    twin = sim.Twin(sim.preset("hp3-paper", seed=5, bench=BENCH))
    twin.write(out)
    truth = json.loads((out / "calib" / "truth.json").read_text())
    return twin, out, truth


def test_bench_dataset_files(bench: Tuple[sim.Twin, Path, Dict[str, Any]]) -> None:
    twin, out, truth = bench
    lines = (out / "calib" / "views.csv").read_text().splitlines()
    assert lines[0] == "board_image,laser_image"
    assert len(lines) == 1 + VIEWS
    rig = json.loads((out / "calib" / "rig.json").read_text())
    assert "robot" not in rig
    for key in ("hand_cam", "base_board", "robot"):
        assert key not in truth
    assert truth["bench"] is True
    assert len(truth["images"]) == VIEWS
    assert [im["sag_mm"] for im in truth["images"]] == [0.0, 1.0, 0.0, 0.0, 0.0]
    assert [im["partial"] for im in truth["images"]] == [False, False, True, False, False]
    # truth.json's poses are the twin's
    for im, v in zip(truth["images"], twin.bench_views()):
        assert im["tilt_deg"] == pytest.approx(v["tilt_deg"])
        assert v["cam_board"].shape == (4, 4)


def _detect(out: Path, name: str, board: stripecal.Board) -> Tuple[np.ndarray, np.ndarray]:
    img = stripecal.load_image(out / "calib" / name)
    det = stripecal.detect_target(img, board)
    return np.asarray(det.indices), np.asarray(det.points)


def test_detections_match_the_true_pose(bench: Tuple[sim.Twin, Path, Dict[str, Any]]) -> None:
    twin, out, truth = bench
    cam = twin.camera
    views = twin.bench_views()
    for i, (im, v) in enumerate(zip(truth["images"], views)):
        if v["partial"] or v["sag_mm"] != 0.0:
            continue
        idx, pts = _detect(out, im["board_image"], twin.board)
        assert len(idx) == twin.board.rows * twin.board.cols, f"view {i}"
        # the true pose projects the circle centres where they are detected: within the
        # centroid's offset from the projected centre (< 0.2 px here) plus the noise
        t = v["cam_board"]
        pitch = twin.config["board"]["pitch_mm"]
        centres = np.column_stack([idx[:, 1] * pitch, idx[:, 0] * pitch, np.zeros(len(idx))])
        proj = cam.project(centres @ t[:3, :3].T + t[:3, 3])
        err = np.hypot(*(proj - pts).T)
        assert err.max() < 0.3, f"view {i}: {err.max():.3f} px"
        # and the exact imaged centroids (truth.json) within the detection noise
        tc = {(c["row"], c["col"]): (c["u"], c["v"]) for c in im["circles"]}
        d = [np.hypot(p[0] - tc[(r, c)][0], p[1] - tc[(r, c)][1]) for (r, c), p in zip(idx, pts)]
        assert max(d) < 0.1, f"view {i}: {max(d):.3f} px"


def _flatness(twin: sim.Twin, out: Path, im: Dict[str, Any], v: Any) -> Any:
    idx, pts = _detect(out, im["board_image"], twin.board)
    return stripecal.board_flatness(twin.camera, twin.board, idx, pts, v["cam_board"])


def test_bowed_view_sag(bench: Tuple[sim.Twin, Path, Dict[str, Any]]) -> None:
    twin, out, truth = bench
    for i, (im, v) in enumerate(zip(truth["images"], twin.bench_views())):
        if v["partial"]:
            continue
        f = _flatness(twin, out, im, v)
        if im["sag_mm"] > 0:
            # 4 sigma plus 0.2 %: the tangent-plane model of the circles against the twin's
            # circles printed on the curved sheet
            assert abs(f["sag_mm"] - im["sag_mm"]) < 4 * f["sigma_mm"] + 0.002 * im["sag_mm"], f
            assert abs(f["sag_mm"]) > 10 * f["sigma_mm"]
        else:
            assert abs(f["sag_mm"]) < 3 * f["sigma_mm"], f"view {i}: {f}"


def test_floor_carries_the_line(bench: Tuple[sim.Twin, Path, Dict[str, Any]]) -> None:
    twin, out, truth = bench
    im = truth["images"][0]
    assert im["floor"] is not None and len(im["floor"]["normal"]) == 3
    pts: List[Dict[str, Any]] = im["stripe"]["points"]
    floor = [p for p in pts if p["surface"] == "flat_plate"]
    board = [p for p in pts if p["surface"] == "board"]
    assert len(floor) > 20 and len(board) > 20
    img = stripecal.load_image(out / "calib" / im["laser_image"])
    vals = [int(img[round(p["v"]), round(p["u"])]) for p in floor]
    assert np.median(vals) > 3 * np.median(img), "the floor's stripe is lit in the laser image"


def test_fixed_sensor_scan(bench: Tuple[sim.Twin, Path, Dict[str, Any]]) -> None:
    twin, out, _ = bench
    lines = (out / "scan" / "scan.csv").read_text().splitlines()
    assert lines[0] == "image"
    truth = json.loads((out / "scan" / "truth.json").read_text())
    assert truth["frame"] == "cam" and len(truth["images"]) == len(lines) - 1
    d = truth["sphere"]["diameter_mm"]
    m = np.array(truth["conveyor"]["direction"])
    c0 = np.array(truth["images"][0]["sphere_center_mm"])
    n, dd = twin.laser_plane
    on = 0
    for k, im in enumerate(truth["images"]):
        c = np.array(im["sphere_center_mm"])
        assert np.allclose(c, c0 + m * k * truth["conveyor"]["step_mm"])
        # every stripe point lies on the ball and the laser plane
        for p in im["stripe"]["points"]:
            ray = twin.camera.unproject(np.array([p["u"], p["v"]]))
            s = dd / float(n @ ray)
            assert abs(np.linalg.norm(ray * s - c) - d / 2) < 1e-3
            on += 1
    assert on > 100
