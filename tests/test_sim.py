"""The digital twin from Python: presets and knobs, rendering, datasets on disk."""

from __future__ import annotations

import json
import typing
from pathlib import Path

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim
import stripecal.types


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
    # every key of a view's truth is one of the typed record's
    assert set(images[0]) <= set(typing.get_type_hints(stripecal.types.TruthImage))
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


# --- robot kinematic calibration (issue 14) ----------------------------------------

ROBOT_ERROR = {"theta0_deg": 0.05, "alpha_deg": 0.02, "a_mm": 0.3, "d_mm": 0.3, "beta_deg": 0.02}
# a quarter-size camera (the paper's, scaled): few pixels to render
TINY_CAMERA = {"width": 192, "height": 144, "fu": 318.0, "fv": 330.6, "u0": 86.5, "v0": 65.6}


def test_robot_error_nominal_rig_true_truth(tmp_path: Path) -> None:
    """`robot_error`: a reproducible random true robot; rig.json keeps the nominal one,
    truth.json holds the true rows (beta only on row 2, alpha 180; row 6 is the last)."""
    assert sim.preset("hp3-paper")["robot_error"]["a_mm"] == 0.0
    cfg = sim.preset(
        "hp3-paper",
        seed=4,
        robot_error=ROBOT_ERROR,
        camera=TINY_CAMERA,
        poses={"count": 1, "margin_px": 3.0},
        scan={"enabled": False},
    )
    twin = sim.Twin(cfg)
    assert twin.robot_true == sim.Twin(cfg).robot_true
    assert twin.robot_true != sim.Twin(sim.preset("hp3-paper", seed=5, robot_error=ROBOT_ERROR)).robot_true
    nominal, true = twin.robot_nominal.dh, twin.robot_true.dh
    np.testing.assert_array_equal(nominal, stripecal.Robot.hp3().dh)
    d = true - nominal
    assert np.all(d != 0) and np.all(np.abs(d) <= 5 * np.array([0.05, 0.02, 0.3, 0.3]))
    beta = twin.robot_true.beta_deg
    assert beta[1] != 0 and abs(beta[1]) < 0.1
    assert np.all(np.delete(beta, 1) == 0)
    twin.write(tmp_path)
    rig = stripecal.load_rig(tmp_path / "calib" / "rig.json")
    assert rig.robot == twin.robot_nominal
    truth = stripecal.load_truth(tmp_path / "calib" / "truth.json")
    assert truth.robot is not None
    np.testing.assert_allclose(truth.robot.dh, true, atol=1e-9)
    np.testing.assert_allclose(truth.robot.beta_deg, beta, atol=1e-12)
    with pytest.raises(stripecal.InvalidInputError, match="robot_error.d_mm"):
        sim.preset("hp3-paper", robot_error={"d_mm": -0.3})
    with pytest.raises(stripecal.InvalidInputError, match="robot_error.tilt"):
        sim.preset("hp3-paper", robot_error={"tilt": 0.3})


def test_calibration_pose_set_wide_spans_more_of_every_joint() -> None:
    wide = sim.calibration_pose_set("hp3-paper", 12, seed=2)
    local = sim.calibration_pose_set("hp3-paper", 12, spread="local", seed=2)
    assert wide.shape == (12, 6) and wide.dtype == np.float64
    np.testing.assert_array_equal(wide, sim.calibration_pose_set(sim.preset("hp3-paper"), 12, seed=2))
    span = lambda q: q.max(axis=0) - q.min(axis=0)  # noqa: E731
    assert np.all(span(wide) >= span(local)), (span(wide), span(local))
    # every constraint holds: the plan passes the twin's check of explicit poses
    checked = sim.Twin(sim.preset("hp3-paper", poses={"explicit_q_deg": wide.tolist()})).calibration_poses()
    assert len(checked) == 12
    with pytest.raises(stripecal.InvalidInputError, match="poses.spread"):
        sim.calibration_pose_set("hp3-paper", 3, spread="far")


def test_table_scan_lies_on_the_true_table(tmp_path: Path) -> None:
    """`scan.table`: a sweep over the bare table; the exact stripe points (the truth of
    one rendered frame) lie on truth.json's table plane."""
    twin = sim.Twin(small(seed=1, scan={"max_frames": 3, "table": True}, robot_error=ROBOT_ERROR))
    qs = twin.table_scan_poses()
    assert qs.shape == (3, 6)
    assert sim.Twin(small()).table_scan_poses().shape == (0, 6)
    truth = twin.truth()
    table = truth.extra["table"]
    assert len(table["normal"]) == 3 and np.isfinite(table["d_mm"])
    frame = twin.render_scan_frame(qs[1])
    assert set(frame["stripe_surface"]) == {"table"}
    pc = frame["stripe_points_cam"]
    t = frame["base_cam"]
    pts = pc @ t[:3, :3].T + t[:3, 3]
    e = sim.surface_errors(pts, truth)
    assert e.shape == (len(pts),) and len(pts) > 100
    assert np.abs(e).max() < 1e-6
    np.testing.assert_allclose(sim.surface_errors(pts + 2.0 * np.asarray(table["normal"]), twin), 2.0, atol=1e-6)
    # the ball scan's points lie on the ball, the plate or the table
    scan = twin.scan_poses()
    f = twin.render_scan_frame(scan[len(scan) // 2])
    assert "sphere" in f["stripe_surface"]
    p = f["stripe_points_cam"] @ f["base_cam"][:3, :3].T + f["base_cam"][:3, 3]
    assert np.abs(sim.surface_errors(p, twin)).max() < 1e-6


def test_simulate_writes_the_verification_artefacts(tmp_path: Path) -> None:
    """`stripecal simulate --set verify.enabled=true`: verify/ with the manifest, the
    certificate and one scan folder per position, each readable as a scan."""
    from stripecal.cli import main

    out = tmp_path / "twin"
    rc = main(["simulate", str(out), "--poses", "3", "--no-scan",
               "--set", "verify.enabled=true", "--set", "verify.bar_positions=1",
               "--set", "verify.plate_positions=1", "--set", "verify.step_mm=6"])
    assert rc == 0
    v = out / "verify"
    assert (v / "verify.csv").read_text() == "scan,artefact\nbar_1,bar\nplate_1,plate\n"
    art = json.loads((v / "artefacts.json").read_text())
    assert art["format"] == "stripecal/artefacts@1"
    assert [s["name"] for s in art["spheres"]] == ["A", "B"]
    assert art["ball_bars"][0]["spheres"] == ["A", "B"]
    assert set(art["mpe_mm"]) == {"probing_form", "probing_size", "sphere_spacing", "flatness"}
    for name in ("bar_1", "plate_1"):
        assert (v / name / "scan.csv").is_file() and (v / name / "rig.json").is_file()
    truth = json.loads((v / "bar_1" / "truth.json").read_text())
    assert [s["name"] for s in truth["spheres"]] == ["A", "B"]
    assert truth["sphere"]["center_mm"] == truth["spheres"][0]["center_mm"]
    assert "plane" in json.loads((v / "plate_1" / "truth.json").read_text())
    twin = sim.Twin(small(verify={"bar_positions": 1, "plate_positions": 1, "step_mm": 6.0}))
    scans = twin.verify_scans()
    assert [s["name"] for s in scans] == ["bar_1", "plate_1"]
    assert scans[0]["poses"].shape[1] == 6 and scans[1]["plane"] is not None
    assert twin.write(tmp_path / "off")["verify_dir"] is None


def _typed_dict(tp):
    """The TypedDict inside an annotation (Optional[X], List[X]...), or None."""
    import typing

    if typing.is_typeddict(tp):
        return tp
    for a in typing.get_args(tp):
        t = _typed_dict(a)
        if t is not None:
            return t
    return None


def _check_keys(value, td, where):
    import typing

    hints = typing.get_type_hints(td)
    # a DH row writes beta_deg only for a parallel joint
    optional = {"beta_deg"} if td is stripecal.types.SimDh else set()
    assert set(hints) - optional <= set(value) <= set(hints), (where, sorted(set(value) ^ set(hints)))
    for k, v in value.items():
        inner = _typed_dict(hints[k])
        items = v if isinstance(v, list) else [v]
        for x in items:
            if isinstance(x, dict):
                assert inner is not None, f"{where}.{k} is a group of knobs without a TypedDict"
                _check_keys(x, inner, f"{where}.{k}")


def test_sim_config_typeddicts_name_the_twins_knobs():
    # every group of knobs of every preset's full configuration (the Rust twin's config
    # as it serialises) has exactly the keys of its TypedDict in stripecal.types
    from stripecal.types import SimConfig

    for name in sim.presets():
        _check_keys(sim.preset(name), SimConfig, name)
    # the groups left null by the presets (a board pose, a DH row with beta_deg)
    cfg = sim.preset("hp3-paper", base_board={"rotation_vector": [0, 0, 0], "translation_mm": [0, 0, 300]})
    _check_keys(cfg, SimConfig, "base_board")
