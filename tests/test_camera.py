"""Camera binding: the model of spec/DATASET.md, round trips and Jacobians."""

from __future__ import annotations

import numpy as np
import pytest

import stripecal

STRONG = {
    "radial1": [-0.3, 0.0, 0.0, 0.0, 0.0],
    "radial2": [-0.3, 0.1, 0.0, 0.0, 0.0],
    "opencv5": [-0.3, 0.1, 1e-3, 1e-3, 0.0],
}


def make(model: str) -> stripecal.Camera:
    return stripecal.Camera(768, 576, 1271.65, 1322.52, 346.14, 262.60, model, STRONG[model])


def model_projection(cam: stripecal.Camera, p: np.ndarray) -> np.ndarray:
    """The spec's formulas, written out independently of the extension."""
    k1, k2, p1, p2, k3 = cam.distortion
    xn, yn = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    r2 = xn**2 + yn**2
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xd = xn * radial + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn**2)
    yd = yn * radial + p1 * (r2 + 2 * yn**2) + 2 * p2 * xn * yn
    return np.stack([cam.fu * xd + cam.u0, cam.fv * yd + cam.v0], axis=1)


def image_grid(cam: stripecal.Camera) -> np.ndarray:
    # pixel centres run from 0 to size-1; the image area from -0.5 to size-0.5
    u = np.linspace(-0.5, cam.width - 0.5, 65)
    v = np.linspace(-0.5, cam.height - 0.5, 49)
    uu, vv = np.meshgrid(u, v)
    return np.stack([uu.ravel(), vv.ravel()], axis=1)


def test_properties_and_params() -> None:
    cam = make("opencv5")
    assert (cam.width, cam.height, cam.size) == (768, 576, (768, 576))
    assert cam.distortion_model == "opencv5"
    assert stripecal.CAMERA_PARAM_NAMES == ("fu", "fv", "u0", "v0", "k1", "k2", "p1", "p2", "k3")
    np.testing.assert_array_equal(
        cam.params, [1271.65, 1322.52, 346.14, 262.60, -0.3, 0.1, 1e-3, 1e-3, 0.0]
    )
    assert cam.with_params(cam.params) == cam
    assert "opencv5" in repr(cam)
    plain = stripecal.Camera(640, 480, 800.0, 800.0, 320.0, 240.0)
    assert plain.distortion_model == "radial1"
    np.testing.assert_array_equal(plain.distortion, np.zeros(5))


@pytest.mark.parametrize("model", sorted(STRONG))
def test_project_follows_the_spec_formulas(model: str) -> None:
    cam = make(model)
    rng = np.random.default_rng(1)
    p = np.column_stack([rng.uniform(-40, 40, 100), rng.uniform(-30, 30, 100), rng.uniform(80, 300, 100)])
    np.testing.assert_allclose(cam.project(p), model_projection(cam, p), rtol=0, atol=1e-9)


@pytest.mark.parametrize("model", sorted(STRONG))
def test_project_unproject_round_trip_over_the_image(model: str) -> None:
    cam = make(model)
    uv = image_grid(cam)
    rays = cam.unproject(uv)
    assert rays.shape == (uv.shape[0], 3)
    np.testing.assert_array_equal(rays[:, 2], 1.0)
    back = cam.project(rays * 137.0)
    assert np.max(np.linalg.norm(back - uv, axis=1)) < 1e-6


def test_single_point_shapes() -> None:
    cam = make("radial2")
    uv = cam.project([10.0, -5.0, 100.0])
    assert uv.shape == (2,)
    assert cam.unproject(uv).shape == (3,)
    a, b, c = cam.project_jacobians([10.0, -5.0, 100.0])
    assert (a.shape, b.shape, c.shape) == ((2,), (2, 3), (2, 9))
    empty = cam.project(np.zeros((0, 3)))
    assert empty.shape == (0, 2)


@pytest.mark.parametrize("model", sorted(STRONG))
def test_jacobians_match_central_differences(model: str) -> None:
    cam = make(model)
    points = np.array([[12.0, -7.0, 100.0], [-40.0, 30.0, 95.0], [1.0, 2.0, 300.0]])
    uv, d_point, d_params = cam.project_jacobians(points)
    assert uv.shape == (3, 2) and d_point.shape == (3, 2, 3) and d_params.shape == (3, 2, 9)
    np.testing.assert_array_equal(uv, cam.project(points))
    for n, p in enumerate(points):
        for k in range(3):
            h = 1e-4 * np.linalg.norm(p)
            a, b = p.copy(), p.copy()
            a[k] += h
            b[k] -= h
            fd = (cam.project(a) - cam.project(b)) / (2 * h)
            col = d_point[n, :, k]
            assert np.max(np.abs(fd - col)) / max(np.linalg.norm(col), 1e-12) < 1e-6
        params = cam.params
        for k in range(9):
            h = 1e-6 * abs(params[k]) if k < 4 else 1e-4
            a, b = params.copy(), params.copy()
            a[k] += h
            b[k] -= h
            fd = (cam.with_params(a).project(p) - cam.with_params(b).project(p)) / (2 * h)
            col = d_params[n, :, k]
            # relative to the column, floored where round-off of u ~ 1e3 px dominates
            assert np.max(np.abs(fd - col)) / max(np.linalg.norm(col), 1e-3) < 1e-6, (
                stripecal.CAMERA_PARAM_NAMES[k]
            )


def test_point_behind_the_camera_names_its_row() -> None:
    cam = make("radial1")
    with pytest.raises(stripecal.DegenerateError, match=r"points\[1\]"):
        cam.project([[0.0, 0.0, 100.0], [0.0, 0.0, -1.0]])


def test_pixel_where_the_model_folds() -> None:
    cam = stripecal.Camera(100, 100, 100.0, 100.0, 50.0, 50.0, "radial1", [-0.5, 0, 0, 0, 0])
    with pytest.raises(stripecal.StripecalError, match=r"pixels\[0\]"):
        cam.unproject([[120.0, 50.0]])
