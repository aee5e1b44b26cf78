"""`stripecal reconstruct` and `stripecal fit-sphere` on a tiny twin scan (5 frames),
reconstructed with the true calibration; bad input leaves no output file."""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Tuple

import numpy as np
import pytest

import stripecal
from stripecal.cli import main


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Tuple[Path, Path, stripecal.Truth]:
    out = tmp_path_factory.mktemp("recon")
    rc = main(["simulate", str(out / "sim"), "--seed", "5", "--poses", "4",
               "--scan-frames", "5", "--scan-step", "3"])
    assert rc == 0
    scan = out / "sim" / "scan"
    truth = stripecal.load_truth(scan / "truth.json")
    cal = stripecal.Calibration(truth.camera, truth.laser_plane, truth.hand_cam, truth.base_board, robot=truth.robot)
    cal_path = out / "calibration.json"
    stripecal.save_calibration(cal_path, cal)
    return cal_path, scan, truth


def test_reconstruct_and_fit_sphere(tiny, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    cal, scan, truth = tiny
    capsys.readouterr()
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(cal), str(scan), "-o", str(ply)]) == 0
    out, err = capsys.readouterr()
    assert "from 5 frames" in out and "points/s" in out and str(ply) in out
    assert "reconstructing" not in err  # no progress bar when stderr is not a terminal
    cloud = stripecal.read_ply(ply)
    assert cloud["points"].shape[1] == 3 and len(cloud["points"]) > 1000
    assert set(np.unique(cloud["properties"]["view"])) == set(range(5))

    sj = tmp_path / "sphere.json"
    assert main(["fit-sphere", str(ply), "-o", str(sj)]) == 0
    out = capsys.readouterr().out
    print(out)
    assert "diameter" in out and "+-" in out and "outliers" in out and "points used" in out
    fit = json.loads(sj.read_text())
    assert {"diameter_mm", "center_mm", "rms_mm", "points", "outliers"} <= set(fit)
    assert "fit_diameter_sigma_mm" in fit and len(fit["fit_center_sigma_mm"]) == 3  # issue 39: fit-only
    sphere = truth.sphere
    assert sphere is not None
    # Five stripes over the ball's middle; stripe centres ~0.06 px RMS on the ball.
    assert abs(fit["diameter_mm"] - sphere["diameter_mm"]) < 0.1
    assert np.linalg.norm(np.array(fit["center_mm"]) - np.array(sphere["center_mm"])) < 0.1

    asc = tmp_path / "cloud_ascii.ply"
    assert main(["reconstruct", str(cal), str(scan), "-o", str(asc), "--ascii"]) == 0
    assert asc.read_bytes().startswith(b"ply\nformat ascii 1.0")
    assert np.array_equal(stripecal.read_ply(asc)["points"], cloud["points"])


def test_calibrate_reconstruct_measure(tiny, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """End to end: calibrate the tiny dataset (4 views: fewer are refused), reconstruct the scan with that
    calibration, fit the ball."""
    _, scan, truth = tiny
    cal = tmp_path / "cal.json"
    assert main(["calibrate", str(scan.parent / "calib"), "-o", str(cal)]) == 0
    ply = tmp_path / "cloud.ply"
    assert main(["reconstruct", str(cal), str(scan), "-o", str(ply)]) == 0
    sj = tmp_path / "sphere.json"
    assert main(["fit-sphere", str(ply), "-o", str(sj)]) == 0
    capsys.readouterr()
    fit = json.loads(sj.read_text())
    sphere = truth.sphere
    assert sphere is not None
    err_d = fit["diameter_mm"] - sphere["diameter_mm"]
    err_c = np.linalg.norm(np.array(fit["center_mm"]) - np.array(sphere["center_mm"]))
    with capsys.disabled():
        print(f"\ncalibrated (4 views) -> ball: diameter {fit['diameter_mm']:.4f} mm (error {err_d:+.4f}), "
              f"centre error {err_c:.4f} mm, {fit['points']} points, {fit['outliers']} outliers")
    # The paper's seven measurements spread +-0.1 mm; the twin's noise is far smaller.
    assert abs(err_d) < 0.05 and err_c < 0.05


def test_reconstruct_bad_scans_write_nothing(tiny, tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    cal, scan, _ = tiny
    ply = tmp_path / "cloud.ply"
    # An empty scan folder.
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["reconstruct", str(cal), str(empty), "-o", str(ply)]) == 1
    assert "scan.csv" in capsys.readouterr().err and not ply.exists()
    # A row naming a missing image.
    bad = tmp_path / "missing"
    shutil.copytree(scan, bad)
    (bad / "images" / "scan_0003.png").unlink()
    assert main(["reconstruct", str(cal), str(bad), "-o", str(ply)]) == 1
    err = capsys.readouterr().err
    assert "line 5" in err and "scan_0003.png" in err and not ply.exists()
    # An image of the wrong size: the frame, its line and the file are named.
    small = tmp_path / "small"
    shutil.copytree(scan, small)
    stripecal.save_image(small / "images" / "scan_0002.png", np.zeros((100, 120), np.uint8))
    assert main(["reconstruct", str(cal), str(small), "-o", str(ply)]) == 1
    err = capsys.readouterr().err
    assert "frame 2" in err and "line 4" in err and "scan_0002.png" in err and "120 x 100" in err
    assert not ply.exists() and not list(tmp_path.glob("*.ply*"))
    # Joint columns that do not match the calibration's robot.
    joints = tmp_path / "joints"
    shutil.copytree(scan, joints)
    (joints / "rig.json").unlink()
    lines = (joints / "scan.csv").read_text().splitlines()
    (joints / "scan.csv").write_text("\n".join(",".join(l.split(",")[:-1]) for l in lines) + "\n")
    assert main(["reconstruct", str(cal), str(joints), "-o", str(ply)]) == 1
    assert "scan.csv" in capsys.readouterr().err and not ply.exists()


def test_fit_sphere_bad_input(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["fit-sphere", str(tmp_path / "nope.ply")]) == 1
    assert "nope.ply" in capsys.readouterr().err
    p = tmp_path / "flat.ply"
    pts = np.stack([np.arange(50.0), (np.arange(50) * 7 % 11).astype(float), np.zeros(50)], axis=1)
    stripecal.write_ply(p, pts)
    assert main(["fit-sphere", str(p), "-o", str(tmp_path / "s.json")]) == 1
    assert "sphere" in capsys.readouterr().err and not (tmp_path / "s.json").exists()
    assert main(["fit-sphere", str(p), "--diameter-range", "10"]) == 1
    assert "MIN,MAX" in capsys.readouterr().err


def test_reconstruct_progress_bar_on_a_terminal(tiny, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """On a terminal the bar shows frames done, frames/s and points/s."""
    import io

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    err = Tty()
    monkeypatch.setattr("sys.stderr", err)
    cal, scan, _ = tiny
    assert main(["reconstruct", str(cal), str(scan), "-o", str(tmp_path / "c.ply")]) == 0
    text = err.getvalue()
    assert "reconstructing" in text and "5/5" in text and "/s" in text and "points/s" in text
