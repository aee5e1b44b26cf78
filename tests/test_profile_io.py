"""A calibrated line profiler's files through the Python API (spec/DATASET.md, "A
profile dataset"): profile files, the profile dataset folder, the profiler's
calibration.json, and the typed errors of each."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stripecal

RIG = {
    "format": "stripecal/rig@1",
    "sensor": {"kind": "profiler", "invalid_z": -99999.9999},
    "artefact": {"kind": "sphere", "diameter_mm": 80.0},
    "robot": {
        "name": "two",
        "joints": [
            {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 300},
            {"theta0_deg": 0, "alpha_deg": 0, "a_mm": 250, "d_mm": 0},
        ],
    },
}


def test_read_profile_points_and_gaps(tmp_path: Path) -> None:
    p = tmp_path / "p.csv"
    p.write_text("intensity,z_mm,x_mm\n9,200.5,-1.25\n3,,0\n4,NaN,1\n5,-99999.9999,2\n7,201.0,3.5\n")
    prof = stripecal.read_profile(p, invalid_z=-99999.9999)
    assert isinstance(prof, stripecal.Profile)
    assert prof.points.dtype == np.float64 and prof.points.shape == (2, 2)
    np.testing.assert_array_equal(prof.points, [[-1.25, 200.5], [3.5, 201.0]])
    assert prof.gaps == 3 and len(prof) == 2
    # without the sentinel, -99999.9999 is a point
    assert stripecal.read_profile(p).gaps == 2


def test_read_profile_errors_name_file_line_and_column(tmp_path: Path) -> None:
    p = tmp_path / "bad.csv"
    p.write_text("x_mm,z_mm\n1,2\n1,abc\n")
    with pytest.raises(stripecal.FormatError) as e:
        stripecal.read_profile(p)
    msg = str(e.value)
    assert "bad.csv" in msg and "line 3, column z_mm" in msg and '"abc"' in msg
    p.write_text("x_mm,y_mm\n1,2\n")
    with pytest.raises(stripecal.FormatError, match=r"line 1: .*no column z_mm"):
        stripecal.read_profile(p)
    with pytest.raises(FileNotFoundError):
        stripecal.read_profile(tmp_path / "none.csv")


def test_load_profile_dataset(tmp_path: Path) -> None:
    (tmp_path / "rig.json").write_text(json.dumps(RIG))
    (tmp_path / "p").mkdir()
    for name in ["a", "b"]:
        (tmp_path / "p" / f"{name}.csv").write_text("x_mm,z_mm\n0,200\n1,-99999.9999\n")
    (tmp_path / "views.csv").write_text("profile,q1,q2\np/a.csv,10,-20\np/b.csv,0,5.5\n")
    ds = stripecal.load_profile_dataset(tmp_path)
    assert len(ds) == 2
    assert ds.profiles == [str(tmp_path / "p" / "a.csv"), str(tmp_path / "p" / "b.csv")]
    assert ds.lines == [2, 3]
    joints = ds.joints
    assert joints is not None
    np.testing.assert_array_equal(joints, [[10.0, -20.0], [0.0, 5.5]])
    assert ds.flange_poses is None
    assert ds.invalid_z == -99999.9999 and ds.sphere_diameter_mm == 80.0
    robot = ds.robot
    assert robot is not None
    # the rig's sentinel is used when a view's profile is read
    assert ds.profile(1).gaps == 1
    # the camera loader refuses a profiler's rig, saying so
    with pytest.raises(stripecal.FormatError, match="describes a profiler"):
        stripecal.load_dataset(tmp_path)
    # image columns are refused by the profile loader
    (tmp_path / "views.csv").write_text("board_image,laser_image,q1,q2\na.png,b.png,0,0\n")
    with pytest.raises(stripecal.FormatError, match=r"views.csv: line 1: .*profile dataset"):
        stripecal.load_profile_dataset(tmp_path)
    # a missing profile names views.csv and its line
    (tmp_path / "views.csv").write_text("profile,q1,q2\np/a.csv,0,0\np/c.csv,0,0\n")
    with pytest.raises(stripecal.FormatError, match=r"views.csv: line 3: profile .*c.csv does not exist"):
        stripecal.load_profile_dataset(tmp_path)


def sample_calibration() -> stripecal.ProfilerCalibration:
    angle = np.deg2rad(170.0)
    c, s = np.cos(angle), np.sin(angle)
    t = np.array([[c, 0, s, 12.5], [0, 1, 0, -3.0], [-s, 0, c, 180.0], [0, 0, 0, 1]])
    return stripecal.ProfilerCalibration(
        t,
        [600.0, -20.5, 310.25],
        80.0012,
        robot=stripecal.Robot.hp3(),
        profile_rms_mm=0.0123,
        views_used=14,
        uncertainty={"sphere": {"center_mm": [0.01, 0.02, 0.03], "diameter_mm": 0.004}},
        extra={"views": [{"view": 0, "rms_mm": 0.01}]},
    )


def test_profiler_calibration_round_trip(tmp_path: Path) -> None:
    cal = sample_calibration()
    path = tmp_path / "calibration.json"
    stripecal.write_profiler_calibration(path, cal)
    back = stripecal.read_profiler_calibration(path)
    # rotation matrices compared (DECISIONS 7)
    np.testing.assert_allclose(back.hand_sensor, cal.hand_sensor, atol=1e-12)
    np.testing.assert_array_equal(back.sphere_center_mm, [600.0, -20.5, 310.25])
    assert back.sphere_diameter_mm == 80.0012
    assert back.quality == {"profile_rms_mm": 0.0123, "views_used": 14, "accepted_poor": False, "checks": []}
    assert back.uncertainty == cal.uncertainty
    assert back.extra == {"views": [{"view": 0, "rms_mm": 0.01}]}
    assert back.covariance is None
    r = back.robot
    assert r is not None and r == stripecal.Robot.hp3()
    doc = json.loads(path.read_text())
    assert doc["sensor"] == {"kind": "profiler"}
    assert "camera" not in doc and "laser_plane" not in doc and "base_board" not in doc
    assert stripecal.ProfilerCalibration.from_json(cal.to_json()) == cal
    # the camera reader refuses it, the profiler reader refuses a camera's
    with pytest.raises(stripecal.FormatError, match="read_profiler_calibration"):
        stripecal.load_calibration(path)
    doc.pop("sensor")
    path.write_text(json.dumps(doc))
    with pytest.raises(stripecal.FormatError, match="calibration.json is a camera's"):
        stripecal.read_profiler_calibration(path)


def test_profiler_calibration_bad_values_are_typed(tmp_path: Path) -> None:
    with pytest.raises(stripecal.InvalidInputError, match="sphere_diameter_mm"):
        stripecal.ProfilerCalibration(np.eye(4), [0, 0, 0], 0.0)
    cal = sample_calibration()
    doc = json.loads(cal.to_json())
    doc["sphere"]["diameter_mm"] = "big"
    with pytest.raises(stripecal.FormatError, match=r"sphere.diameter_mm"):
        stripecal.ProfilerCalibration.from_json(json.dumps(doc))
