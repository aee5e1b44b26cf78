"""stripecal.extract_stripe and stripecal.fit_line: API shapes and types, accuracy on a
twin view, bad input (issue 3, acceptance 7: typed errors, no panic, no hang)."""

from __future__ import annotations

from typing import Any, Dict

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim


@pytest.fixture(scope="module")
def view() -> Dict[str, Any]:
    twin = sim.Twin(sim.preset("hp3-paper", seed=0))
    q = twin.calibration_poses()[0]["q_deg"]
    v = twin.render_view(q)
    v["direction"] = twin.stripe_direction
    return v


def test_extract_stripe_shapes_and_types(view: Dict[str, Any]) -> None:
    s = stripecal.extract_stripe(view["laser_image"], board_image=view["board_image"])
    m = len(s)
    assert m > 400
    assert s.direction == view["direction"] == "cols"
    assert s.points.shape == (m, 2) and s.points.dtype == np.float64
    assert s.intensity.shape == (m,) and s.intensity.dtype == np.float64
    assert s.width.shape == (m,) and s.width.dtype == np.float64
    assert s.flags.shape == (m,) and s.flags.dtype == np.uint8
    for mask in (s.edge, s.saturated, s.low_signal, s.trusted):
        assert mask.shape == (m,) and mask.dtype == np.bool_
    # one point per row, in row order, rows are integers
    assert np.all(np.diff(s.points[:, 1]) > 0)
    assert np.all(s.points[:, 1] == np.round(s.points[:, 1]))
    assert np.all((s.width > 1) & (s.width < 24))
    assert s.edge.any(), "the board image flags the circle borders"
    assert np.array_equal(s.trusted, (s.flags & stripecal.Stripe.BIASED) == 0)
    assert set(s.rejected) == {"no_peak", "multiple_peaks", "saturated", "shape", "border", "isolated"}
    assert s.lines == 576
    assert "Stripe(" in repr(s)


def test_accuracy_on_a_twin_view(view: Dict[str, Any]) -> None:
    s = stripecal.extract_stripe(view["laser_image"], board_image=view["board_image"])
    mask = s.trusted
    pts = s.points[mask]
    truth = view["stripe_points"][np.array(view["stripe_surface"]) == "board"]
    rows = {int(round(t[1])): t[0] for t in truth}
    e = np.array([abs(p[0] - rows[int(p[1])]) for p in pts if int(p[1]) in rows])
    assert len(e) > 150
    assert np.sqrt(np.mean(e**2)) < 0.03
    # the board part is a straight line
    on_board = np.array([int(p[1]) in rows for p in pts])
    f = stripecal.fit_line(pts[on_board])
    assert f.rms_px < 0.05 and f.inlier_count > 0.95 * on_board.sum()


@pytest.mark.parametrize("method", ["centroid", "gaussian"])
@pytest.mark.parametrize("direction", ["auto", "cols"])
def test_methods_and_directions(view: Dict[str, Any], method: str, direction: str) -> None:
    s = stripecal.extract_stripe(view["laser_image"], direction=direction, method=method)
    assert s.direction == "cols" and len(s) > 400


def test_rows_direction_on_the_transposed_image(view: Dict[str, Any]) -> None:
    img = view["laser_image"]
    a = stripecal.extract_stripe(img, direction="cols")
    b = stripecal.extract_stripe(img.T, direction="auto")  # non-contiguous view: copied
    assert b.direction == "rows"
    assert np.allclose(a.points, b.points[:, ::-1], atol=1e-6)


def test_uint16_and_single_image(view: Dict[str, Any]) -> None:
    img16 = view["laser_image"].astype(np.uint16) * 257
    a = stripecal.extract_stripe(view["laser_image"])
    b = stripecal.extract_stripe(img16)
    assert len(a) == len(b)
    assert np.allclose(a.points, b.points, atol=1e-3)
    # the same array as board image: single-image mode (the stripe's footprint ignored)
    one = np.clip(view["board_image"].astype(np.int32) // 2 + view["laser_image"], 0, 255).astype(np.uint8)
    s = stripecal.extract_stripe(one, board_image=one)
    assert len(s) > 400 and not s.edge.all()


def test_bad_images_raise_typed_errors() -> None:
    with pytest.raises(stripecal.InvalidInputError, match="empty"):
        stripecal.extract_stripe(np.zeros((0, 10), np.uint8))
    with pytest.raises(stripecal.InvalidInputError, match="3 or 4"):
        stripecal.extract_stripe(np.zeros((10, 10, 2), np.uint8))
    with pytest.raises(stripecal.InvalidInputError, match="2D"):
        stripecal.extract_stripe(np.zeros((10, 10, 3, 1), np.uint8))
    with pytest.raises(stripecal.DetectionError):  # colour is accepted: no stripe in it
        stripecal.extract_stripe(np.zeros((10, 10, 3), np.uint8), channel="red")
    with pytest.raises(TypeError, match="uint8 or uint16"):
        stripecal.extract_stripe(np.zeros((10, 10), np.float32))
    with pytest.raises(TypeError):
        stripecal.extract_stripe([[1, 2], [3, 4]])
    with pytest.raises(stripecal.InvalidInputError, match="direction"):
        stripecal.extract_stripe(np.zeros((10, 10), np.uint8), direction="diagonal")
    with pytest.raises(stripecal.InvalidInputError, match="method"):
        stripecal.extract_stripe(np.zeros((10, 10), np.uint8), method="magic")
    with pytest.raises(stripecal.InvalidInputError, match="board_image"):
        stripecal.extract_stripe(np.zeros((10, 10), np.uint8), board_image=np.zeros((5, 5), np.uint8))


@pytest.mark.parametrize(
    "image",
    [
        np.zeros((1, 1), np.uint8),
        np.zeros((576, 768), np.uint8),
        np.full((576, 768), 255, np.uint8),
        np.full((100, 100), 65535, np.uint16),
        np.random.default_rng(0).integers(0, 256, (576, 768)).astype(np.uint8),
        np.random.default_rng(1).normal(40, 2, (576, 768)).clip(0, 255).astype(np.uint8),
        np.random.default_rng(2).integers(0, 65536, (300, 200)).astype(np.uint16),
    ],
    ids=["1-pixel", "all-black", "all-white", "all-white-16", "uniform-noise", "gaussian-noise", "noise-16"],
)
def test_no_stripe_is_a_detection_error(image: np.ndarray) -> None:
    with pytest.raises(stripecal.StripecalError, match="no stripe found"):
        stripecal.extract_stripe(image)


def test_fit_line_with_outliers() -> None:
    rng = np.random.default_rng(3)
    t = np.linspace(0, 500, 300)
    pts = np.stack([120 + 0.25 * t, t], axis=1) + rng.normal(0, 0.03, (300, 2))
    out = rng.choice(300, 60, replace=False)
    pts[out, 0] += rng.uniform(5, 80, 60)
    f = stripecal.fit_line(pts)
    assert f.inlier_count == 240
    assert not f.inliers[out].any()
    d = f.direction
    assert abs(abs(d[0] / d[1]) - 0.25) < 1e-3 and d[1] > 0
    assert np.allclose(f.normal, [-d[1], d[0]])
    assert f.rms_px < 0.06 and f.max_px < 0.2
    assert f.distances(pts[~np.isin(np.arange(300), out)]).std() < 0.06
    assert f.inliers.dtype == np.bool_ and f.point.shape == (2,)
    # deterministic
    assert np.array_equal(stripecal.fit_line(pts).inliers, f.inliers)


def test_fit_line_bad_input() -> None:
    with pytest.raises(stripecal.InvalidInputError, match="at least 2"):
        stripecal.fit_line(np.zeros((1, 2)))
    with pytest.raises(stripecal.InvalidInputError, match=r"\(N, 2\)"):
        stripecal.fit_line(np.zeros((5, 3)))
    with pytest.raises(stripecal.InvalidInputError, match="finite"):
        stripecal.fit_line([[0, 0], [1, np.nan], [2, 2]])
    with pytest.raises(stripecal.DegenerateError):
        stripecal.fit_line([[1, 1], [1, 1], [1, 1]])
    with pytest.raises(TypeError):
        stripecal.fit_line("points")
