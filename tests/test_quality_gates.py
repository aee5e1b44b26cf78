"""Issue 13: a calibration that is not trustworthy fails loudly: the CLI exits non-zero
and writes nothing, Python raises ``CalibrationQualityError`` carrying the calibration
for inspection, ``--accept-poor`` writes it marked. The twin renders one 5-view dataset
per module; the false-alarm campaign over seeds runs ``STRIPECAL_GATE_SEEDS`` seeds per
noise level (default 1; the acceptance run is ``python scripts/gate_false_alarms.py 20``).
"""

from __future__ import annotations

import csv
import os
import shutil
from pathlib import Path
from typing import List

import pytest

import stripecal
import stripecal.sim
from stripecal.cli import main


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("gates")
    cfg = stripecal.sim.preset("hp3-paper", {"seed": 5, "scan": {"enabled": False}})
    stripecal.sim.Twin(cfg).write(str(out))
    return out / "calib"


def _swapped(clean: Path, dest: Path, i: int, j: int) -> Path:
    """A copy of the dataset with the images of views i and j swapped (the poses stay)."""
    shutil.copytree(clean, dest)
    with open(clean / "views.csv", newline="") as f:
        rows: List[List[str]] = list(csv.reader(f))
    head, body = rows[0], rows[1:]
    for col in (head.index("board_image"), head.index("laser_image")):
        body[i][col], body[j][col] = body[j][col], body[i][col]
    with open(dest / "views.csv", "w", newline="") as f:
        csv.writer(f).writerows([head] + body)
    return dest


def test_clean_dataset_passes_every_gate(clean: Path, tmp_path: Path) -> None:
    cal = stripecal.calibrate(clean, leave_one_out=False)
    q = cal.quality
    # board_scale: the DECISIONS 5 gate (issue 38)
    assert [c["name"] for c in q["checks"]] == ["pairing", "views", "determined", "converged", "board_scale"]
    assert all(c["passed"] and c["views"] == [] for c in q["checks"])
    assert q["accepted_poor"] is False
    cal.save(tmp_path / "c.json")
    back = stripecal.load_calibration(tmp_path / "c.json").quality
    assert back["checks"] == q["checks"] and back["accepted_poor"] is False


def test_two_swapped_views_of_five_fail_and_nothing_is_written(clean: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    ds = _swapped(clean, tmp_path / "swapped", 1, 3)
    out = tmp_path / "calibration.json"
    assert main(["calibrate", str(ds), "-o", str(out), "--no-leave-one-out"]) == 1
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir()] == ["swapped"]  # no temp file either
    err = capsys.readouterr().err
    assert "views 1 and 3" in err and "nothing written" in err and "look swapped" in err
    # Python: the error carries the failed check and the calibration to inspect
    with pytest.raises(stripecal.CalibrationQualityError) as info:
        stripecal.calibrate(ds, leave_one_out=False)
    e = info.value
    assert isinstance(e, ValueError) and isinstance(e, stripecal.StripecalError)
    assert [c["name"] for c in e.checks] == ["pairing"] and e.checks[0]["views"] == [1, 3]
    assert e.calibration is not None and e.calibration.quality["views_used"] == 3
    # --accept-poor writes it, marked
    assert main(["calibrate", str(ds), "-o", str(out), "--accept-poor", "--no-leave-one-out"]) == 0
    assert "ACCEPTED POOR" in capsys.readouterr().out
    q = stripecal.load_calibration(out).quality
    assert q["accepted_poor"] is True
    assert [c["passed"] for c in q["checks"] if c["name"] == "pairing"] == [False]


def test_an_existing_output_is_left_alone_when_the_gates_fail(clean: Path, tmp_path: Path) -> None:
    ds = _swapped(clean, tmp_path / "swapped", 0, 4)
    out = tmp_path / "calibration.json"
    out.write_text("previous calibration")
    assert main(["calibrate", str(ds), "-o", str(out), "--no-leave-one-out"]) == 1
    assert out.read_text() == "previous calibration"


@pytest.mark.parametrize("noise", [1.0, 4.0])
def test_good_calibrations_are_not_rejected(noise: float, tmp_path: Path) -> None:
    seeds = int(os.environ.get("STRIPECAL_GATE_SEEDS", "1"))
    for seed in range(seeds):
        cfg = stripecal.sim.preset("hp3-paper", {"seed": 100 + seed, "imaging": {"noise_gray": noise},
                                                 "scan": {"enabled": False}})
        out = tmp_path / f"s{seed}"
        stripecal.sim.Twin(cfg).write(str(out))
        cal = stripecal.calibrate(out / "calib", leave_one_out=False)
        assert all(c["passed"] and c["views"] == [] for c in cal.quality["checks"]), cal.quality["checks"]


def test_report_shows_the_checks_and_the_accepted_poor_banner(clean: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from stripecal.report import write_report

    ds = _swapped(clean, tmp_path / "swapped", 2, 4)
    cal = stripecal.calibrate(ds, leave_one_out=False, accept_poor=True)
    text = write_report(tmp_path / "rep", cal).read_text()
    assert "Quality checks" in text and "ACCEPTED POOR" in text and "FAILED" in text
    assert "views 2 and 4" in text
