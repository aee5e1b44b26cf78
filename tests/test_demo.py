"""`stripecal demo` end to end with a smaller ball scan (issue 5, acceptance 1 and 5):
the twin of the paper's rig (5 calibration poses, noise 1, PSF 0.7) is calibrated, the
ball reconstructed and fitted; centre and diameter against the truth; the report's PNGs
are real images referenced by the HTML."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stripecal
from stripecal.cli import main


def test_demo_small_scan_measures_the_ball_and_writes_the_report(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("matplotlib")
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--scan-step", "1.5"]) == 0
    text = capsys.readouterr().out
    for s in ("paper Table 2", "fu (px)", "X tx (mm)", "reference ball", "CMM value 44.8614", "+0.080"):
        assert s in text, s
    for f in ("calibration.json", "cloud.ply", "sphere.json", "report/index.html", "calib/truth.json", "scan/scan.csv"):
        assert (out / f).exists(), f
    truth = stripecal.load_truth(out / "scan" / "truth.json").sphere
    assert truth is not None
    fit = json.loads((out / "sphere.json").read_text())
    d_err = fit["diameter_mm"] - truth["diameter_mm"]
    c_err = float(np.linalg.norm(np.array(fit["center_mm"]) - np.array(truth["center_mm"])))
    print(f"demo (scan step 1.5 mm): diameter error {d_err:+.4f} mm, centre error {c_err:.4f} mm")
    assert abs(d_err) <= 0.01 and c_err <= 0.05
    page = (out / "report" / "index.html").read_text()
    pngs = sorted((out / "report").glob("*.png"))
    assert len(pngs) == 5
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 5000
        assert f'src="{p.name}"' in page
    assert "Demo results" in page
