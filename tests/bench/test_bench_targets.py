"""stripecal.detect_target against OpenCV's detector for each target kind, on the same
768 x 576 twin board images (view 0 of each preset), timed in the same run (issue 10,
acceptance 5: at least 3x faster; circle grid under 2 ms in criterion).

    STRIPECAL_BENCH=1 python -m pytest tests/bench/test_bench_targets.py -s

The peers (BENCHMARKS.md names them): circles `cv2.findCirclesGrid(...,
CALIB_CB_SYMMETRIC_GRID)` and `(..., CALIB_CB_ASYMMETRIC_GRID)` with its default blob
detector; chessboards `cv2.findChessboardCornersSB(..., CALIB_CB_NORMALIZE_IMAGE |
CALIB_CB_EXHAUSTIVE | CALIB_CB_ACCURACY)`. Build the extension in release mode first
(``MATURIN_PEP517_ARGS=--release pip install -e .``).
"""

from __future__ import annotations

import statistics
import time
from typing import Any, Callable, Dict

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim

cv2 = pytest.importorskip("cv2")

PRESETS = {"circles": "hp3-paper", "asymmetric_circles": "hp3-asymmetric", "chessboard": "hp3-chessboard"}


@pytest.fixture(scope="module")
def views() -> Dict[str, Dict[str, Any]]:
    out = {}
    for kind, name in PRESETS.items():
        twin = sim.Twin(sim.preset(name))
        v = twin.render_view(twin.calibration_poses()[0]["q_deg"], 0)
        v["board"] = twin.board
        out[kind] = v
    return out


def ours(v: Dict[str, Any]) -> Any:
    return stripecal.detect_target(v["board_image"], v["board"])


def opencv(v: Dict[str, Any]) -> Any:
    b, img = v["board"], v["board_image"]
    if b.kind == "chessboard":
        flags = cv2.CALIB_CB_NORMALIZE_IMAGE | cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
        ok, c = cv2.findChessboardCornersSB(img, (b.cols, b.rows), flags=flags)
    else:
        grid = cv2.CALIB_CB_ASYMMETRIC_GRID if b.kind == "asymmetric_circles" else cv2.CALIB_CB_SYMMETRIC_GRID
        ok, c = cv2.findCirclesGrid(img, (b.cols, b.rows), flags=grid)
    assert ok
    return c


@pytest.mark.parametrize("kind", list(PRESETS))
def test_bench_stripecal(benchmark: Any, views: Dict[str, Dict[str, Any]], kind: str) -> None:
    benchmark.group = f"{kind} 768x576"
    d = benchmark(ours, views[kind])
    assert len(d) == len(views[kind]["board"])


@pytest.mark.parametrize("kind", list(PRESETS))
def test_bench_opencv(benchmark: Any, views: Dict[str, Dict[str, Any]], kind: str) -> None:
    benchmark.group = f"{kind} 768x576"
    c = benchmark(opencv, views[kind])
    assert len(c) == len(views[kind]["board"])


def median_time(f: Callable[[], Any], runs: int) -> float:
    ts = []
    for _ in range(runs):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


@pytest.mark.parametrize("kind", list(PRESETS))
def test_speed_ratio(views: Dict[str, Dict[str, Any]], kind: str) -> None:
    """Both detectors timed in the same run, interleaved (median of 5 rounds of 10)."""
    v = views[kind]
    a, b = [], []
    for _ in range(5):
        a.append(median_time(lambda: ours(v), 10))
        b.append(median_time(lambda: opencv(v), 10))
    t_ours, t_cv = float(np.median(a)), float(np.median(b))
    print(
        f"\n{kind}: detect_target {t_ours * 1e3:.2f} ms, OpenCV {t_cv * 1e3:.2f} ms "
        f"(cv2 threads {cv2.getNumThreads()}): ratio {t_cv / t_ours:.1f}x"
    )
    assert t_cv / t_ours >= 3.0
