"""Pose planning (``stripecal.plan_poses``, ``stripecal plan``) on a twin dataset folder
with its truth.json as the nominal calibration."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stripecal
import stripecal.sim
from stripecal.cli import main


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("plan_twin")
    twin = stripecal.sim.Twin(stripecal.sim.preset("hp3-paper", seed=4, scan={"enabled": False}, poses={"count": 8}))
    twin.write(out)
    return out / "calib"


def _joints(folder: Path) -> np.ndarray:
    ds = stripecal.load_dataset(folder)
    return np.asarray([v["joints"] for v in ds.views], dtype=np.float64)


def test_plan_poses_from_a_dataset_folder_and_truth(dataset: Path) -> None:
    joints = _joints(dataset)
    plan = stripecal.plan_poses(dataset, dataset / "truth.json", joints)
    assert plan["usable"] == len(joints) == len(plan["poses"])
    for p in plan["poses"]:
        assert p["usable"] and p["reason"] is None and p["points"] >= 4 and p["stripe_points"] > 100
        assert p["standoff_mm"] is not None and 80.0 < p["standoff_mm"] < 160.0
    names = [e["name"] for e in plan["parameters"]]
    for n in ["camera.fu", "laser_plane.d_mm", "hand_cam.translation_mm[2]", "base_board.rotation_vector[0]"]:
        assert n in names
    assert all(np.isfinite(e["sigma"]) and e["sigma"] > 0 for e in plan["parameters"])
    cov = np.asarray(plan["covariance"])
    assert cov.shape == (len(names), len(names))
    assert np.allclose(np.sqrt(np.diag(cov)), [e["sigma"] for e in plan["parameters"]])
    pt = plan["point"]
    assert pt is not None and pt["sigma_base_norm_mm"] is not None
    assert 0 < pt["sigma_camera_norm_mm"] < 1.0
    # The same from objects; the noise scales every sigma.
    truth = stripecal.load_truth(dataset / "truth.json")
    rig = stripecal.load_rig(dataset / "rig.json")
    twice = stripecal.plan_poses(rig, truth, joints, sigma_px=(0.1, 0.2))
    for a, b in zip(plan["parameters"], twice["parameters"]):
        assert a["name"] == b["name"] and b["sigma"] == pytest.approx(2 * a["sigma"], rel=1e-6)
    # Holding blocks removes their rows.
    held = stripecal.plan_poses(rig, truth, joints, fix=["camera"])
    assert not any(e["name"].startswith("camera.") for e in held["parameters"])


def test_plan_uses_the_calibrations_pose_noise(dataset: Path, tmp_path: Path) -> None:
    """Issue 38: the plan's adjustment has the calibration's noise model. With a twin's
    truth (an exact robot, no figures) the robot is planned exact; a robot-pose noise
    given, or the one an earlier calibration estimated, widens X's and Z's sigmas and
    is reported."""
    joints = _joints(dataset)
    exact = stripecal.plan_poses(dataset, dataset / "truth.json", joints)
    assert exact["pose_noise_mm_deg"] is None
    noisy = stripecal.plan_poses(dataset, dataset / "truth.json", joints, pose_noise=(0.2, 0.02))
    assert noisy["pose_noise_mm_deg"] == pytest.approx([0.2, 0.02])
    sig = {e["name"]: e["sigma"] for e in exact["parameters"]}
    wider = {e["name"]: e["sigma"] for e in noisy["parameters"]}
    assert wider["hand_cam.translation_mm[0]"] > 2 * sig["hand_cam.translation_mm[0]"]
    assert wider["base_board.translation_mm[2]"] > 2 * sig["base_board.translation_mm[2]"]
    # An earlier calibration's estimate is planned with when nothing is given.
    cal = stripecal.calibrate(dataset, leave_one_out=False)
    rn = cal.robot_pose_noise
    assert rn is not None
    from_cal = stripecal.plan_poses(dataset, cal, joints)
    assert from_cal["pose_noise_mm_deg"] == pytest.approx([rn["translation_mm"], rn["rotation_deg"]])
    with pytest.raises(stripecal.InvalidInputError, match="pose_noise"):
        stripecal.plan_poses(dataset, dataset / "truth.json", joints, pose_noise=(-1.0, 0.1))
    out = tmp_path / "plan.json"
    poses = tmp_path / "poses.csv"
    poses.write_text("q1,q2,q3,q4,q5,q6\n" + "\n".join(",".join(f"{x:.6f}" for x in q) for q in joints) + "\n")
    assert main(["plan", "--rig", str(dataset), "--nominal", str(dataset / "truth.json"), "--poses", str(poses),
                 "--pose-noise", "0.2,0.02", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["pose_noise_mm_deg"] == pytest.approx([0.2, 0.02])


def test_plan_poses_errors(dataset: Path) -> None:
    joints = _joints(dataset)
    with pytest.raises(stripecal.InvalidInputError, match="usable"):
        stripecal.plan_poses(dataset, dataset / "truth.json", joints[:2])
    with pytest.raises(stripecal.InvalidInputError, match="pose 0"):
        stripecal.plan_poses(dataset, dataset / "truth.json", joints[:, :5])
    with pytest.raises(TypeError):
        stripecal.plan_poses(3, dataset / "truth.json", joints)  # type: ignore[arg-type]


def test_cli_plan(dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "plan.json"
    rc = main(["plan", "--rig", str(dataset), "--nominal", str(dataset / "truth.json"),
               "--poses", str(dataset / "views.csv"), "--noise-px", "0.05", "--standoff", "110", "--json", str(out)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert "pose  usable  points  stripe  stand-off mm" in text
    assert "camera.fu" in text and "laser_plane.d_mm" in text and "hand_cam (X)" in text
    assert "point on the laser plane at 110.0 mm" in text
    plan = json.loads(out.read_text())
    assert set(plan) == {"poses", "usable", "sigma_px", "points", "stripe_points", "parameters", "covariance",
                         "state", "point", "warnings", "robot_held", "pose_noise_mm_deg"}
    assert plan["point"]["standoff_mm"] == 110.0
    assert not list(tmp_path.glob("*.tmp*"))


def test_cli_plan_bad_poses_file(dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    poses = tmp_path / "poses.csv"
    poses.write_text("q1,q2,q3,q4,q5,q6\n0,0,0,0,-90,0\n0,0,0,0,-90\n")
    rc = main(["plan", "--rig", str(dataset / "rig.json"), "--nominal", str(dataset / "truth.json"),
               "--poses", str(poses)])
    err = capsys.readouterr().err
    assert rc == 1
    assert f"{poses}: line 3:" in err and "5 fields" in err
    from stripecal.cli import _read_poses_csv

    with pytest.raises(stripecal.FormatError, match="line 3"):
        _read_poses_csv(str(poses))
