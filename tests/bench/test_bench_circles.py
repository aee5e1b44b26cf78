"""stripecal.detect_circles vs cv2.findCirclesGrid on the same 768 x 576 twin board image
(hp3-paper, view 0: 88 circles). Acceptance 5: ours at least 3x faster.

    STRIPECAL_BENCH=1 python -m pytest tests/bench -s

Build the extension in release mode first (``pip install .`` or
``MATURIN_PEP517_ARGS=--release pip install -e .``); the dev build of scripts/test.sh
is much slower.
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


@pytest.fixture(scope="module")
def view() -> Dict[str, Any]:
    twin = sim.Twin("hp3-paper")
    v = twin.render_view(twin.calibration_poses()[0]["q_deg"], 0)
    v["board"] = twin.board
    return v


def ours(v: Dict[str, Any]) -> Any:
    return stripecal.detect_circles(v["board_image"], v["board"])


def opencv(v: Dict[str, Any]) -> Any:
    b = v["board"]
    ok, c = cv2.findCirclesGrid(v["board_image"], (b.cols, b.rows), flags=cv2.CALIB_CB_SYMMETRIC_GRID)
    assert ok
    return c


def test_bench_stripecal_detect_circles(benchmark: Any, view: Dict[str, Any]) -> None:
    benchmark.group = "circles 768x576"
    idx, _ = benchmark(ours, view)
    assert len(idx) == 88


def test_bench_opencv_find_circles_grid(benchmark: Any, view: Dict[str, Any]) -> None:
    benchmark.group = "circles 768x576"
    c = benchmark(opencv, view)
    assert len(c) == 88


def median_time(f: Callable[[], Any], runs: int) -> float:
    ts = []
    for _ in range(runs):
        t0 = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def test_speed_ratio(view: Dict[str, Any]) -> None:
    """Both detectors timed in the same run, interleaved (median of 5 rounds of 10)."""
    a, b = [], []
    for _ in range(5):
        a.append(median_time(lambda: ours(view), 10))
        b.append(median_time(lambda: opencv(view), 10))
    t_ours, t_cv = float(np.median(a)), float(np.median(b))
    print(
        f"\ndetect_circles {t_ours * 1e3:.2f} ms, cv2.findCirclesGrid {t_cv * 1e3:.2f} ms "
        f"(cv2 threads {cv2.getNumThreads()}): ratio {t_cv / t_ours:.1f}x"
    )
    assert t_cv / t_ours >= 3.0
