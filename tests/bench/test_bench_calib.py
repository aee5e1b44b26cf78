"""Calibration speed from detected points (issue 4, acceptance 6), Python side: OpenCV's
cv2.calibrateCamera + cv2.calibrateRobotWorldHandEye on the circle centres of a 15-view
hp3-paper twin dataset, beside stripecal.calibrate_camera on the same points and the
whole stripecal.calibrate (detection included) of the same folder.

    STRIPECAL_BENCH=1 python -m pytest tests/bench/test_bench_calib.py -s

Our whole calibration from points (one thread) is the criterion bench
`cargo bench -p stripecal-benches --bench calib`; run both in one session and record
them together in BENCHMARKS.md.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, List, Tuple

import numpy as np
import pytest

import stripecal
import stripecal.sim

cv2 = pytest.importorskip("cv2")

pytestmark = pytest.mark.skipif(
    not os.environ.get("STRIPECAL_BENCH"), reason="benchmarks run with STRIPECAL_BENCH=1"
)


@pytest.fixture(scope="module")
def points(tmp_path_factory: pytest.TempPathFactory) -> Tuple[Path, List[Any], Any]:
    out = tmp_path_factory.mktemp("bench")
    stripecal.sim.Twin(stripecal.sim.preset("hp3-paper", poses={"count": 15}, scan={"enabled": False})).write(out)
    path = out / "calib"
    ds = stripecal.load_dataset(path)
    views = [stripecal.detect_circles(stripecal.load_image(path / n), ds.rig.board) for n in ds.board_images]
    return path, views, ds


def test_opencv_calibrate_camera_and_robot_world_hand_eye(benchmark: Any, points: Tuple[Path, List[Any], Any]) -> None:
    _, views, ds = points
    centers = ds.rig.board.centers()
    index_of = {(int(r), int(c)): k for k, (r, c) in enumerate(ds.rig.board.indices())}
    obj = [np.ascontiguousarray(centers[[index_of[(int(r), int(c))] for r, c in idx]], np.float32) for idx, _ in views]
    img = [np.ascontiguousarray(ctr, np.float32) for _, ctr in views]
    b2g = [np.linalg.inv(a) for a in ds.base_hand()]
    flags = cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST

    def run() -> None:
        _, _, _, rvecs, tvecs = cv2.calibrateCamera(obj, img, (768, 576), None, None, flags=flags)
        r = [cv2.Rodrigues(v)[0] for v in rvecs]
        cv2.calibrateRobotWorldHandEye(r, list(tvecs), [m[:3, :3] for m in b2g], [m[:3, 3].reshape(3, 1) for m in b2g])

    benchmark(run)


def test_stripecal_calibrate_camera_same_points(benchmark: Any, points: Tuple[Path, List[Any], Any]) -> None:
    _, views, ds = points
    benchmark(lambda: stripecal.calibrate_camera(views, ds.rig.board, (768, 576)))


def test_stripecal_calibrate_whole_folder(benchmark: Any, points: Tuple[Path, List[Any], Any]) -> None:
    path, _, _ = points
    benchmark.pedantic(lambda: stripecal.calibrate(path), rounds=3, iterations=1)
