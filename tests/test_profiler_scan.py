"""A line profiler's scan (issue 18, item 6): the twin's ball scanned by the profiler,
reconstructed with the profiler's calibration and measured with its GUM budget."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Tuple

import numpy as np
import pytest

import stripecal
import stripecal.sim as sim
from stripecal.cli import main


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Tuple[Path, stripecal.ProfilerCalibration]:
    out = tmp_path_factory.mktemp("profiler_scan")
    sim.Twin(sim.preset("hp3-profiler", seed=7)).write(str(out))
    cal = stripecal.calibrate(str(out / "calib"), leave_one_out=False)
    assert isinstance(cal, stripecal.ProfilerCalibration)
    return out, cal


def test_scan_sphere_diameter_within_its_expanded_uncertainty(calibrated: Tuple[Path, stripecal.ProfilerCalibration]) -> None:
    out, cal = calibrated
    truth = sim.profiler_truth(str(out / "scan"))
    d_true = float(truth["sphere"]["diameter_mm"])
    c_true = np.asarray(truth["sphere"]["center_mm"], float)
    m = stripecal.measure_sphere(cal, str(out / "scan"), diameter_range_mm=(0.8 * d_true, 1.2 * d_true))
    u = m["uncertainty"]
    err = m["diameter_mm"] - d_true
    assert abs(err) <= u["diameter"]["expanded_mm"], (err, u["diameter"])
    # the calibration part is carried (the hand-eye's covariance moves the centre)
    assert u["center"][0]["calibration_mm"] > 0.0
    for k in range(3):
        assert abs(m["center_mm"][k] - c_true[k]) <= u["center"][k]["expanded_mm"], (k, u["center"][k])
    # a profiler has no stripe-bias correction to apply
    assert m.get("stripe_bias") is None


def test_reconstruct_profile_scan_cli_writes_sensor_coordinates(calibrated: Tuple[Path, stripecal.ProfilerCalibration], tmp_path: Path) -> None:
    out, cal = calibrated
    cal_path = tmp_path / "cal.json"
    cal.save(str(cal_path))
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(cal_path), str(out / "scan"), "-o", str(ply)]) == 0
    header = ply.read_bytes().split(b"end_header")[0].decode()
    assert "property double x_mm" in header and "property double z_mm" in header
    cloud = stripecal.reconstruct_scan(cal, str(out / "scan"), covariance=True)
    assert len(cloud) > 10000
    # every point lies near the true sphere or below it on the table/stand; the sphere's
    # points within a few noise sigmas of its surface
    truth = sim.profiler_truth(str(out / "scan"))
    c = np.asarray(truth["sphere"]["center_mm"], float)
    d = np.linalg.norm(cloud.points - c, axis=1) - 0.5 * float(truth["sphere"]["diameter_mm"])
    on = np.abs(d) < 0.1
    assert on.sum() > 0.5 * len(cloud)
    assert float(np.sqrt(np.mean(d[on] ** 2))) < 0.012
    cov = cloud.covariance
    assert cov is not None and cov.shape == (len(cloud), 3, 3) and np.all(np.diagonal(cov, axis1=1, axis2=2) > 0)
    assert os.path.getsize(ply) > 0


def test_verify_on_a_profile_scan(calibrated: Tuple[Path, stripecal.ProfilerCalibration], tmp_path: Path) -> None:
    """`stripecal verify` with a profiler's calibration: the scan of the twin's ball as a
    probing test against a certificate (the twin's diameter, as a certificate would give)."""
    import json
    import shutil

    out, cal = calibrated
    folder = tmp_path / "verify"
    shutil.copytree(out / "scan", folder / "ball")
    d = float(sim.profiler_truth(str(out / "scan"))["sphere"]["diameter_mm"])
    (folder / "verify.csv").write_text("scan,artefact\nball,ball\n")
    (folder / "artefacts.json").write_text(json.dumps({
        "format": "stripecal/artefacts@1",
        "spheres": [{"name": "ball", "diameter_mm": d, "form_mm": 0.0005}],
        "ball_bars": [], "planes": [],
        "uncertainty_k2_mm": {"diameter": 0.001, "length": 0.002, "flatness": 0.001},
        "mpe_mm": {"probing_form": 0.05, "probing_size": 0.01, "sphere_spacing": 0.08, "flatness": 0.05}}))
    r = stripecal.verify(cal, str(folder))
    rows = {row["characteristic"]: row for row in r["rows"]}
    size = rows["probing_size"]
    # the size error is within its expanded uncertainty, and the MPE of 0.01 mm is met
    assert abs(size["budget"]["value_mm"]) <= size["budget"]["expanded_mm"] + 1e-12, size
    assert size["passed"] and rows["probing_form"]["passed"], r
    cal_path = tmp_path / "cal.json"
    cal.save(str(cal_path))
    assert main(["verify", str(cal_path), str(folder)]) == 0
