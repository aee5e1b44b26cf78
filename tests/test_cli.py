"""The stripecal command line."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

import stripecal
from stripecal.cli import main


def test_info_prints_the_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info"]) == 0
    assert capsys.readouterr().out.strip() == f"stripecal {stripecal.__version__}"


def test_info_verbose(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", "--verbose"]) == 0
    out = capsys.readouterr().out
    assert "numpy" in out and "extension" in out


def test_no_command_prints_help_and_fails(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert "usage" in capsys.readouterr().err


def test_module_entry_point() -> None:
    proc = subprocess.run([sys.executable, "-m", "stripecal", "info"], capture_output=True, text=True)
    assert proc.returncode == 0 and stripecal.__version__ in proc.stdout


@pytest.mark.skipif(shutil.which("stripecal") is None, reason="console script not on PATH")
def test_console_script() -> None:
    proc = subprocess.run(["stripecal", "--version"], capture_output=True, text=True)
    assert proc.returncode == 0 and stripecal.__version__ in proc.stdout


def test_simulate_writes_datasets_and_prints_a_summary(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "sim"
    rc = main(["simulate", str(out), "--seed", "3", "--poses", "3", "--scan-frames", "2",
               "--noise", "0.5", "--set", "imaging.vignetting=0.2", "--set", "camera.distortion_model=radial2"])
    assert rc == 0
    text = capsys.readouterr().out
    assert "calibration views: 3" in text and "88/88" in text and str(out / "calib") in text
    rig = stripecal.load_rig(out / "calib" / "rig.json")
    assert rig.distortion_model == "radial2"
    assert len(stripecal.load_scan(out / "scan").images) == 2
    cfg = stripecal.load_truth(out / "calib" / "truth.json").extra["sim_config"]
    assert cfg["imaging"]["vignetting"] == 0.2 and cfg["imaging"]["noise_gray"] == 0.5 and cfg["seed"] == 3


def test_simulate_rejects_unknown_knobs(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["simulate", str(tmp_path), "--set", "imaging.nosie=1"]) == 1
    assert "imaging.nosie" in capsys.readouterr().err
    assert not (tmp_path / "calib").exists()


def test_demo_small(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["demo", "--out", str(tmp_path / "d"), "--scan-frames", "2"]) == 0
    text = capsys.readouterr().out
    assert "hp3-paper" in text and "calibration views: 5" in text and "ball scan: 2 stripe images" in text
    assert (tmp_path / "d" / "calib" / "views.csv").exists()


def test_detect_prints_every_view_and_writes_points(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """`stripecal detect DATASET --csv FILE` on a twin dataset of an asymmetric grid: every
    view detected and its points written; `--rig RIG IMAGE...` with a wrong board size
    refuses each image with the reason and exits 1."""
    assert main(["simulate", str(tmp_path / "d"), "--preset", "hp3-asymmetric", "--poses", "3",
                 "--set", "scan.enabled=false"]) == 0
    capsys.readouterr()
    csv_path = tmp_path / "points.csv"
    assert main(["detect", str(tmp_path / "d" / "calib"), "--csv", str(csv_path)]) == 0
    out = capsys.readouterr().out
    assert "board: asymmetric_circles 11 x 8, 3 images" in out and "3 of 3 images detected" in out
    lines = csv_path.read_text().splitlines()
    assert lines[0] == "view,row,col,u,v,flags" and len(lines) == 1 + 3 * 88
    rig = json.loads((tmp_path / "d" / "calib" / "rig.json").read_text())
    rig["board"]["cols"] = 7
    (tmp_path / "wrong.json").write_text(json.dumps(rig))
    images = sorted(str(p) for p in (tmp_path / "d" / "calib" / "images").glob("*board*"))
    assert main(["detect", "--rig", str(tmp_path / "wrong.json"), *images]) == 1
    out = capsys.readouterr().out
    assert "0 of 3 images detected" in out and "larger than the board" in out
