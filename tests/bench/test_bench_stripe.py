"""stripecal.extract_stripe on a 768 x 576 twin laser image (hp3-paper, view 0), from
Python, beside a plain memory read of the same image (issue 3, acceptance 5).

    STRIPECAL_BENCH=1 python -m pytest tests/bench/test_bench_stripe.py -s

The Python figure includes the binding's copy of the array (the GIL is released while
Rust extracts). Build the extension in release mode first (``pip install .`` or
``MATURIN_PEP517_ARGS=--release pip install -e .``); figures go to BENCHMARKS.md.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim

pytestmark = pytest.mark.skipif(
    not os.environ.get("STRIPECAL_BENCH"), reason="benchmarks run with STRIPECAL_BENCH=1"
)


@pytest.fixture(scope="module")
def laser_image() -> np.ndarray:
    twin = sim.Twin("hp3-paper")
    v = twin.render_view(twin.calibration_poses()[0]["q_deg"], 0)
    img: np.ndarray = v["laser_image"]
    assert img.shape == (576, 768) and img.dtype == np.uint8
    return img


def test_memory_read(benchmark: Any, laser_image: np.ndarray) -> None:
    """The physical limit: every pixel read once (numpy sum)."""
    benchmark(lambda: int(laser_image.sum(dtype=np.uint32)))


@pytest.mark.parametrize("direction", ["cols", "auto"])
def test_extract_stripe(benchmark: Any, laser_image: np.ndarray, direction: str) -> None:
    s = benchmark(lambda: stripecal.extract_stripe(laser_image, direction=direction))
    assert s.direction == "cols" and len(s) > 500
    benchmark.extra_info["images_per_s"] = 1.0 / benchmark.stats.stats.mean


def test_extract_stripe_gaussian(benchmark: Any, laser_image: np.ndarray) -> None:
    s = benchmark(lambda: stripecal.extract_stripe(laser_image, direction="cols", method="gaussian"))
    assert len(s) > 500
