"""The digital twin from Python: presets and knobs, rendering, datasets on disk."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim


def small(seed: int = 0, **knobs: object) -> dict:
    over = {"poses": {"count": 3}, "scan": {"max_frames": 3}}
    over.update(knobs)  # type: ignore[arg-type]
    return sim.preset("hp3-paper", over, seed=seed)


def test_presets_and_overrides() -> None:
    assert "hp3-paper" in sim.presets()
    cfg = sim.preset("hp3-paper", imaging={"noise_gray": 2.5}, seed=4)
    assert cfg["imaging"]["noise_gray"] == 2.5
    assert cfg["imaging"]["psf_sigma_px"] == 0.7  # untouched knob keeps the preset value
    assert cfg["seed"] == 4
    assert cfg["camera"]["fu"] == 1271.65 and cfg["camera"]["width"] == 768
    with pytest.raises(stripecal.InvalidInputError, match="imaging.nosie"):
        sim.preset("hp3-paper", imaging={"nosie": 1})
    with pytest.raises(stripecal.InvalidInputError, match="bit_depth"):
        sim.preset("hp3-paper", imaging={"bit_depth": 12})
    with pytest.raises(stripecal.InvalidInputError, match="unknown preset"):
        sim.preset("nope")


def test_true_parameters_are_the_papers() -> None:
    twin = sim.Twin("hp3-paper")
    n, d = twin.laser_plane
    np.testing.assert_allclose(n, np.array([0.6290, -0.0492, 0.7759]) / np.linalg.norm([0.6290, -0.0492, 0.7759]))
    assert d == pytest.approx(79.8728 / np.linalg.norm([0.6290, -0.0492, 0.7759]))
    rv = stripecal.matrix_to_rotvec(twin.hand_cam[:3, :3])
    np.testing.assert_allclose(rv, [-0.3087, 0.2362, 3.0369], atol=1e-12)
    np.testing.assert_allclose(twin.hand_cam[:3, 3], [29.19, 5.37, 62.64], atol=1e-12)
    np.testing.assert_allclose(twin.robot_nominal.dh, stripecal.Robot.hp3().dh)


def test_render_view_shapes_and_truth() -> None:
    twin = sim.Twin(small(seed=2))
    poses = twin.calibration_poses()
    assert len(poses) == 3
    v = twin.render_view(poses[0]["q_deg"], 0)
    assert v["board_image"].shape == (576, 768) and v["board_image"].dtype == np.uint8
    assert v["laser_image"].shape == (576, 768)
    assert v["circle_indices"].shape == (88, 2) and v["circle_centers"].shape == (88, 2)
    # the imaged-circle centre is not the projected circle centre (perspective)
    shift = np.linalg.norm(v["circle_centers"] - v["circle_centers_projected"], axis=1)
    assert 0 < shift.max() < 1.0
    # the true centres are where the image is dark
    img = v["board_image"].astype(float)
    c = np.round(v["circle_centers"]).astype(int)
    assert img[c[:, 1], c[:, 0]].mean() < 0.3 * np.median(img)
    assert v["stripe_points"].shape[1] == 2 and len(v["stripe_surface"]) == len(v["stripe_points"])
    # the stripe is bright in the laser image where the truth says it is
    lp = np.round(v["stripe_points"]).astype(int)
    laser = v["laser_image"].astype(float)
    assert laser[lp[:, 1], lp[:, 0]].mean() > 4 * np.median(laser)


def test_single_image_16_bit() -> None:
    twin = sim.Twin(small(imaging={"single_image": True, "bit_depth": 16}))
    v = twin.render_view(twin.calibration_poses()[0]["q_deg"])
    assert v["laser_image"] is None
    assert v["board_image"].dtype == np.uint16


def test_write_dataset_loads_and_is_deterministic(tmp_path: Path) -> None:
    twin = sim.Twin(small(seed=5))
    calls = []
    summary = twin.write(tmp_path / "a", lambda stage, done, total: calls.append((stage, done, total)))
    assert calls[-1][1] == calls[-1][2]
    ds = stripecal.load_dataset(tmp_path / "a" / "calib")
    assert len(ds) == 3
    np.testing.assert_array_equal(ds.joints, np.array([v["q_deg"] for v in summary["views"]]))
    truth = stripecal.load_truth(tmp_path / "a" / "calib" / "truth.json")
    assert truth.camera == twin.camera
    scan = stripecal.load_scan(tmp_path / "a" / "scan")
    assert len(scan.images) == 3
    assert stripecal.load_truth(tmp_path / "a" / "scan" / "truth.json").sphere["diameter_mm"] == 44.8614
    # same seed, same bytes
    sim.Twin(small(seed=5)).write(tmp_path / "b")
    for name in ["images/view_000_board.png", "images/view_002_laser.png", "views.csv"]:
        assert (tmp_path / "a" / "calib" / name).read_bytes() == (tmp_path / "b" / "calib" / name).read_bytes()


def test_reading_noise_moves_the_readings_not_the_images(tmp_path: Path) -> None:
    """`poses.reading_noise_deg`: views.csv reports noisy joint readings, the images (and
    the true readings in truth.json) stay those of the true poses."""
    assert sim.preset("hp3-paper")["poses"]["reading_noise_deg"] == 0.0
    cfg = small(seed=5, scan={"enabled": False}, poses={"count": 3, "reading_noise_deg": 0.05})
    sim.Twin(cfg).write(tmp_path / "noisy")
    sim.Twin(small(seed=5, scan={"enabled": False})).write(tmp_path / "exact")
    noisy = stripecal.load_dataset(tmp_path / "noisy" / "calib").joints
    exact = stripecal.load_dataset(tmp_path / "exact" / "calib").joints
    d = noisy - exact
    assert d.shape == (3, 6) and 0 < np.abs(d).max() < 0.3
    images = stripecal.load_truth(tmp_path / "noisy" / "calib" / "truth.json").extra["images"]
    np.testing.assert_allclose(np.array([im["q_deg"] for im in images]), exact, atol=1e-9)
    np.testing.assert_allclose(np.array([im["q_reading_deg"] for im in images]), noisy, atol=1e-9)
    for name in ["images/view_001_board.png", "images/view_002_laser.png"]:
        assert (tmp_path / "noisy" / "calib" / name).read_bytes() == (tmp_path / "exact" / "calib" / name).read_bytes()


def test_progress_callback_errors_propagate(tmp_path: Path) -> None:
    def boom(stage: str, done: int, total: int) -> None:
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        sim.Twin(small()).write(tmp_path, boom)


def test_bad_joint_vector() -> None:
    twin = sim.Twin(small())
    with pytest.raises(stripecal.InvalidInputError, match=r"shape \(6,\)"):
        twin.render_view([0.0, 1.0])
