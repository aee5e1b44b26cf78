"""Rotation helpers."""

from __future__ import annotations

import numpy as np

import stripecal


def test_rotvec_round_trip() -> None:
    rng = np.random.default_rng(2)
    for _ in range(100):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        angle = rng.uniform(0, np.pi - 1e-6)
        r = axis * angle
        m = stripecal.rotvec_to_matrix(r)
        assert m.shape == (3, 3)
        np.testing.assert_allclose(m.T @ m, np.eye(3), atol=1e-14)
        assert np.linalg.det(m) > 0
        np.testing.assert_allclose(stripecal.matrix_to_rotvec(m), r, atol=1e-9)


def test_rotvec_is_rodrigues() -> None:
    m = stripecal.rotvec_to_matrix([0.0, 0.0, np.pi / 2])
    np.testing.assert_allclose(m, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)


def test_nearest_rotation() -> None:
    r = stripecal.rotvec_to_matrix([0.2, -0.4, 1.1])
    noisy = r + 1e-3 * np.array([[1, -2, 0], [0.5, 0, 1], [-1, 0, 2]])
    n = stripecal.nearest_rotation(noisy)
    assert abs(np.linalg.det(n) - 1) < 1e-12
    np.testing.assert_allclose(n, r, atol=5e-3)
    assert abs(np.linalg.det(stripecal.nearest_rotation(-r)) - 1) < 1e-12
