"""Measurements with budgets (issue 15) on one rendered hp3-paper twin (5 poses, noise 1,
PSF 0.7 px: the acceptance conditions), rendered and calibrated once for the module:
the ball's budget against the truth, the per-point covariance's stripe part against
finite differences of the reconstruction, the CLI, bad input."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Tuple

import numpy as np
import pytest

import stripecal
from stripecal import sim
from stripecal.cli import main


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Tuple[Path, stripecal.Calibration, stripecal.Truth]:
    root = tmp_path_factory.mktemp("measure")
    cfg = sim.preset("hp3-paper", seed=3, poses={"count": 5}, imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7})
    summary = sim.Twin(cfg).write(root)
    cal = stripecal.calibrate(summary["calib_dir"])
    truth = stripecal.load_truth(root / "scan" / "truth.json")
    return root, cal, truth


@pytest.fixture(scope="module")
def ball(rig: Any) -> Any:
    """The ball measured with the defaults (once for the module)."""
    root, cal, truth = rig
    d0 = float(truth.sphere["diameter_mm"])
    return stripecal.measure_sphere(cal, root / "scan", diameter_range_mm=(0.8 * d0, 1.2 * d0))


def test_ball_budget_covers_the_truth(rig: Any, ball: Any) -> None:
    root, cal, truth = rig
    sphere = truth.sphere
    d0 = float(sphere["diameter_mm"])
    c0 = np.asarray(sphere["center_mm"])
    m = ball
    u = m["uncertainty"]
    rows = [("diameter", m["diameter_mm"] - d0, u["diameter"])]
    rows += [(f"centre {a}", m["center_mm"][k] - c0[k], u["center"][k]) for k, a in enumerate("xyz")]
    for name, err, b in rows:
        print(f"{name}: error {err:+.5f} mm, U {b['expanded_mm']:.5f} (random {b['random_mm']:.1e}, "
              f"calibration {b['calibration_mm']:.1e}, systematic {b['systematic_mm']:.1e})")
        parts = np.array([b["random_mm"], b["calibration_mm"], b["robot_mm"], b["systematic_mm"]])
        assert b["combined_mm"] == pytest.approx(np.sqrt(np.sum(parts**2)), rel=1e-12)
        assert b["expanded_mm"] == pytest.approx(2.0 * b["combined_mm"], rel=1e-12) and b["k"] == 2.0
        assert b["calibration_mm"] > 0 and b["random_mm"] > 0 and b["robot_mm"] == 0.0
    # The diameter's U covers the truth; the coverage of every quantity is pooled over 20
    # seeds in scripts/measurement_acceptance.py (one seed is one draw).
    assert abs(rows[0][1]) <= rows[0][2]["expanded_mm"], "diameter: the truth is outside U"
    # Issue 15, item 2 on this seed: diameter within 0.002 mm, centre within 0.005 mm.
    assert abs(m["diameter_mm"] - d0) < 0.002
    assert np.linalg.norm(np.asarray(m["center_mm"]) - c0) < 0.005
    bias = m["stripe_bias"]
    assert bias is not None and bias["diameter_change_mm"] < 0  # pulled back inwards
    # The twin's stripe clips near the emitter: those of the ball's points are left out of
    # the corrected fit and counted (at most the scan's saturated points, trimmed ones
    # aside).
    cloud = stripecal.reconstruct_scan(cal, root / "scan")
    in_scan = int(np.count_nonzero(cloud.flags & stripecal.Stripe.SATURATED))
    assert isinstance(bias["points_saturated"], int)
    assert 0 < bias["points_saturated"] <= in_scan
    # Without the correction the diameter is the known +0.004-0.005 mm too large.
    raw = stripecal.measure_sphere(cal, root / "scan", diameter_range_mm=(0.8 * d0, 1.2 * d0), correct_bias=False)
    assert 0.003 < raw["diameter_mm"] - d0 < 0.007 and raw["stripe_bias"] is None
    # The corrected fit uses the uncorrected one's points less the unmodelled.
    assert m["points"] <= raw["points"] - bias["points_saturated"]
    # The calibration part alone is what calibration_part=False leaves out.
    nocal = stripecal.measure_sphere(cal, root / "scan", diameter_range_mm=(0.8 * d0, 1.2 * d0),
                                     calibration_part=False)
    assert nocal["uncertainty"]["diameter"]["calibration_mm"] == 0.0
    # Nothing to carry the emitter estimate into, and said why.
    assert nocal["calibration_emitter"] is not None and not nocal["calibration_emitter"]["applied"]
    assert "calibration" in nocal["calibration_emitter"]["reason"]
    assert nocal["uncertainty"]["diameter"]["random_mm"] == pytest.approx(u["diameter"]["random_mm"], rel=1e-9)


def test_the_emitter_estimate_is_carried_into_the_calibration(rig: Any, ball: Any, tmp_path: Path) -> None:
    """The sphere's emitter estimate replaces the calibration's assumed emitter range
    (docs/measurement.md, "The emitter carried into the calibration")."""
    root, cal, truth = rig
    d0 = float(truth.sphere["diameter_mm"])
    rng = (0.8 * d0, 1.2 * d0)
    m = ball
    ce = m["calibration_emitter"]
    assert ce is not None and ce["applied"] and ce["reason"] is None, ce
    # The twin's emitter is where the calibration assumes it (n d): the estimate lands
    # near it, and no estimate counts for better than the 5 mm floor.
    assert max(abs(x) for x in ce["offset_mm"]) < 3.0, ce
    assert min(ce["sd_mm"]) >= 5.0
    # The same calibration without the board correction's response: nothing carried,
    # the +-30 mm range stays in the calibration part.
    cal.save(tmp_path / "cal.json")
    j = json.loads((tmp_path / "cal.json").read_text())
    del j["board_stripe_bias"]["emitter_response"]
    (tmp_path / "plain.json").write_text(json.dumps(j))
    plain = stripecal.measure_sphere(stripecal.load_calibration(tmp_path / "plain.json"), root / "scan",
                                     diameter_range_mm=rng)
    assert plain["calibration_emitter"] is None
    part = lambda r, k: r["uncertainty"]["center"][k]["calibration_mm"]  # noqa: E731
    for k in range(3):
        assert part(m, k) <= part(plain, k) * (1 + 1e-9), k
    # The range term leaves centre z's calibration part. It was most of it with the rigid
    # model of wave two (the part fell by more than 5 %); with the robot-pose noise and the
    # covariance widened to the views' own scatter (issue 38), the calibration's other
    # uncertainty on this 5-view rendered rig is larger (1.57 um) and the range's share
    # is about 0.2 um of it (1.572 -> 1.558 um).
    assert part(m, 2) < (1 - 1e-3) * part(plain, 2), (part(m, 2), part(plain, 2))
    # The values move by the calibration's response at the estimate: near n d, a small
    # fraction of a micrometre.
    assert abs(m["diameter_mm"] - plain["diameter_mm"]) < 2e-4
    assert np.max(np.abs(np.asarray(m["center_mm"]) - plain["center_mm"])) < 3e-4


def test_point_covariance_stripe_part_and_robot_figures(rig: Any) -> None:
    root, cal, _ = rig
    base = stripecal.reconstruct_scan(cal, root / "scan", covariance=True, stripe_sigma_px=0.0)
    more = stripecal.reconstruct_scan(cal, root / "scan", covariance=True, stripe_sigma_px=0.2)
    plain = stripecal.reconstruct_scan(cal, root / "scan")
    assert plain.covariance is None
    c0, c1 = base.covariance, more.covariance
    assert c0 is not None and c1 is not None and c0.shape == (len(base), 3, 3)
    assert np.allclose(c0, np.transpose(c0, (0, 2, 1)))
    assert np.all(np.linalg.eigvalsh(c1) > -1e-15)
    # The stripe part: 0.2^2 dp/du dp/du^T, dp/du by central differences of triangulate.
    scan = stripecal.load_scan(root / "scan")
    joints = scan.joints
    assert joints is not None and cal.robot is not None
    h = 1e-3
    for i in np.linspace(0, len(base) - 1, 7).astype(int):
        f = int(base.frame[i])
        bh = cal.robot.forward(joints[f])
        uv = np.array([[base.u[i] + h, base.v[i]], [base.u[i] - h, base.v[i]]])
        pts, idx = stripecal.triangulate(cal, uv, bh)
        assert list(idx) == [0, 1]
        g = (pts[0] - pts[1]) / (2 * h)
        assert np.allclose(c1[i] - c0[i], 0.04 * np.outer(g, g), rtol=1e-5, atol=1e-12)
    # The robot's figures add sigma^2 I (repeatability) to every point.
    rep = stripecal.reconstruct_scan(cal, root / "scan", covariance=True, stripe_sigma_px=0.0, repeatability_mm=0.01)
    assert rep.covariance is not None
    assert np.allclose(rep.covariance - c0, 1e-4 * np.eye(3), atol=1e-12)


def test_cli_measure_prints_the_budget_and_writes_json(rig: Any, tmp_path: Path, capsys: Any) -> None:
    root, cal, _ = rig
    cal_path = tmp_path / "cal.json"
    cal.save(cal_path)
    out = tmp_path / "ball.json"
    assert main(["measure", str(cal_path), str(root / "scan"), "--diameter-range", "35,55", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "diameter" in text and "U (k=2)" in text and "stripe bias corrected" in text
    rec = json.loads(out.read_text())
    for key in ("diameter_mm", "center_mm", "rms_mm", "points", "outliers"):
        assert key in rec  # the contract's sphere-fit keys
    assert rec["uncertainty"]["diameter"]["k"] == 2.0
    cloud = tmp_path / "c.ply"
    assert main(["reconstruct", str(cal_path), str(root / "scan"), "-o", str(cloud), "--covariance"]) == 0
    ply = stripecal.read_ply(cloud)
    assert "cov_xx" in ply["properties"] and len(ply["properties"]["cov_zz"]) == len(ply["points"])


def test_bad_input(rig: Any, tmp_path: Path) -> None:
    root, cal, _ = rig
    p = tmp_path / "old.json"
    cal.save(p)
    doc = json.loads(p.read_text())
    del doc["covariance"]
    p.write_text(json.dumps(doc))
    old = stripecal.load_calibration(p)
    with pytest.raises(stripecal.InvalidInputError, match="no covariance"):
        stripecal.measure_sphere(old, root / "scan")
    # The calibration part off: an old file still measures.
    m = stripecal.measure_sphere(old, root / "scan", calibration_part=False, diameter_range_mm=(35, 55))
    assert m["uncertainty"]["diameter"]["calibration_mm"] == 0.0
    with pytest.raises(stripecal.InvalidInputError, match="stripe_sigma_px"):
        stripecal.measure_sphere(cal, root / "scan", stripe_sigma_px=-1.0)
    # A cloud of another (longer) scan.
    cloud = stripecal.reconstruct_scan(cal, root / "scan")
    short = tmp_path / "short"
    short.mkdir()
    lines = (root / "scan" / "scan.csv").read_text().splitlines()
    (short / "scan.csv").write_text("\n".join(lines[:5]) + "\n")
    (short / "images").symlink_to(root / "scan" / "images")
    with pytest.raises(stripecal.InvalidInputError, match="not this scan's cloud"):
        stripecal.measure_sphere(cal, short, cloud=cloud)
