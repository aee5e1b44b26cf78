"""The twin's profiler mode (issue 18) from Python: the preset renders a profile dataset
and a scan in the files of spec/DATASET.md, and the truth reads back."""

import csv
import math

import numpy as np
import pytest

import stripecal.sim as sim


def _rot(rv):
    """Rodrigues: the rotation matrix of a rotation vector (radians)."""
    v = np.asarray(rv, dtype=float)
    a = float(np.linalg.norm(v))
    if a < 1e-15:
        return np.eye(3)
    k = v / a
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(a) * kx + (1 - math.cos(a)) * kx @ kx


def test_profiler_preset_writes_the_contract_files(tmp_path):
    cfg = sim.preset("hp3-profiler", seed=5, profiler={"views": 6, "scan_frames": 8})
    assert "hp3-profiler" in sim.presets()
    s = sim.Twin(cfg).write(tmp_path)
    calib = tmp_path / "calib"
    for name in ("rig.json", "views.csv", "truth.json"):
        assert (calib / name).is_file()
    with open(calib / "views.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows[0] == ["profile", "q1", "q2", "q3", "q4", "q5", "q6"]
    assert len(rows) == 7
    for r in rows[1:]:
        assert (calib / r[0]).is_file()
    prof = s["profiler"]
    assert prof is not None and len(prof["views"]) == 6 and len(prof["scan"]) == 8
    assert prof["sphere_points"] > 6 * 500 and prof["gaps"] > 0 and prof["spikes"] > 0
    t = sim.profiler_truth(calib)
    assert t["sensor"]["kind"] == "profiler"
    assert t["sphere"]["diameter_mm"] == 80.0
    assert len(t["views"]) == 6 and len(t["robot"]["joints"]) == 6
    # the truth agrees with the summary and with the geometry of the pose: the sphere
    # centre in the sensor frame is T_sensor_base C with T_base_sensor = T_base_hand X
    hc, c = t["hand_cam"], np.asarray(t["sphere"]["center_mm"])
    for v, sv in zip(t["views"], prof["views"]):
        assert v["sphere_center_sensor_mm"] == pytest.approx(sv["sphere_center_sensor_mm"], abs=1e-12)
        bh = v["base_hand"]
        r = _rot(bh["rotation_vector"]) @ _rot(hc["rotation_vector"])
        p = _rot(bh["rotation_vector"]) @ np.asarray(hc["translation_mm"]) + np.asarray(bh["translation_mm"])
        cs = r.T @ (c - p)
        assert cs == pytest.approx(v["sphere_center_sensor_mm"], abs=1e-6)
        assert 200.0 - 1e-6 <= cs[2] <= 250.0 + 1e-6 and 4.0 - 1e-6 <= abs(cs[1]) <= 30.0 + 1e-6
    scan = sim.profiler_truth(tmp_path / "scan" / "truth.json")
    assert len(scan["frames"]) == 8
    with open(tmp_path / "scan" / "scan.csv", newline="") as f:
        assert next(csv.reader(f))[0] == "profile"


def test_profiler_truth_refuses_a_camera_truth(tmp_path):
    (tmp_path / "truth.json").write_text('{"format": "stripecal/truth@1", "camera": {}}')
    with pytest.raises(ValueError, match="profiler"):
        sim.profiler_truth(tmp_path)


def test_simulate_cli_summarises_a_profiler_twin(tmp_path, capsys):
    from stripecal.cli import main

    out = tmp_path / "sim"
    rc = main(["simulate", str(out), "--preset", "hp3-profiler", "--seed", "2",
               "--set", "profiler.views=2", "--set", "profiler.scan_frames=3"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "calibration views: 2 profiles" in text and "profiles/" in text
    assert "3 profiles" in text and "circles" not in text
    t = sim.profiler_truth(out / "calib")
    assert t["seed"] == 2 and len(t["views"]) == 2
