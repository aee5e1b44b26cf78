"""Issue 17: the sensor on the bench (a dataset without pose columns).

The bench dataset is the robot twin's calibration dataset with the pose columns removed
from views.csv (the twin has no bench mode yet): same images, board poses free. Rendered
once for the module. Every figure is checked against the twin's truth.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
from pathlib import Path
from typing import Dict, Tuple

import numpy as np
import pytest

import stripecal as sc
from stripecal import sim

SEED = 3


def _strip_poses(path: Path, names: int) -> None:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    with open(path, "w") as f:
        for r in rows:
            f.write(",".join(r[:names]) + "\n")


@pytest.fixture(scope="module")
def twin(tmp_path_factory: pytest.TempPathFactory) -> Tuple[Path, Path, Dict]:
    root = tmp_path_factory.mktemp("bench")
    cfg = sim.preset(
        "hp3-paper",
        seed=SEED,
        poses={"count": 15},
        imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
        # The scan's tests need a few frames over the ball, not the whole sweep.
        scan={"max_frames": 12},
    )
    sim.Twin(cfg).write(root / "twin")
    bench = root / "bench"
    shutil.copytree(root / "twin" / "calib", bench)
    _strip_poses(bench / "views.csv", 2)
    truth = json.loads((bench / "truth.json").read_text())
    return root, bench, truth


@pytest.fixture(scope="module")
def bench_cal(twin: Tuple[Path, Path, Dict]) -> sc.Calibration:
    return sc.calibrate(twin[1])


def test_a_views_csv_without_pose_columns_is_a_bench_dataset(twin: Tuple[Path, Path, Dict]) -> None:
    ds = sc.load_dataset(twin[1])
    assert ds.is_bench and len(ds) == 15
    assert ds.joints is None and ds.flange_poses is None
    assert ds.views[0]["joints"] is None and ds.views[0]["flange_pose"] is None
    robot = sc.load_dataset(twin[0] / "twin" / "calib")
    assert not robot.is_bench


def test_bench_calibration_meets_the_targets_and_its_sigmas(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict]
) -> None:
    truth = twin[2]
    cam, tc = bench_cal.camera, truth["camera"]
    plane = bench_cal.laser_plane
    assert plane is not None
    n, d = plane
    u = bench_cal.uncertainty
    uc, up = u["camera"], u["laser_plane"]
    # The targets (noise 1 gray level, PSF 0.7 px, 15 views).
    assert abs(cam.fu - tc["fu"]) <= 1e-4 * tc["fu"]
    assert abs(cam.u0 - tc["u0"]) <= 0.1 and abs(cam.v0 - tc["v0"]) <= 0.1
    assert abs(d - truth["laser_plane"]["d_mm"]) <= 0.01
    # Against the reported uncertainty: every number within 5 sigma (the twin's
    # images hold small systematic effects the noise model does not; see
    # scripts/bench_acceptance.py for the coverage over 10 seeds).
    pairs = [
        (cam.fu - tc["fu"], uc["fu"]),
        (cam.fv - tc["fv"], uc["fv"]),
        (cam.u0 - tc["u0"], uc["u0"]),
        (cam.v0 - tc["v0"], uc["v0"]),
        (d - truth["laser_plane"]["d_mm"], up["d_mm"]),
    ]
    pairs += [(n[k] - truth["laser_plane"]["normal"][k], up["normal"][k]) for k in range(3)]
    for err, sigma in pairs:
        assert sigma > 0 and abs(err) <= 5 * sigma, (err, sigma)
    # The leave-one-view-out figure: stripe points against each held-out view's own
    # board plane, mm; the noise (0.02 px stripe sigma at ~1300 px / 110 mm) makes it a
    # few micrometres.
    loo = bench_cal.leave_one_out
    assert loo is not None and len(loo["views"]) == 15
    assert loo["median_stripe_rms_mm"] is not None and loo["median_stripe_rms_mm"] < 0.01


def test_bench_calibration_json_has_no_robot_blocks(
    bench_cal: sc.Calibration, tmp_path: Path
) -> None:
    out = tmp_path / "bench.json"
    bench_cal.save(out)
    doc = json.loads(out.read_text())
    for key in ("hand_cam", "base_board", "robot"):
        assert key not in doc
    cov = doc["covariance"]
    assert cov["parameters"][:4] == ["camera.fu", "camera.fv", "camera.u0", "camera.v0"]
    assert "laser_plane.d_mm" in cov["parameters"]
    m = np.array(cov["matrix"])
    assert m.shape == (len(cov["parameters"]),) * 2
    i = cov["parameters"].index("camera.fu")
    assert math.isclose(math.sqrt(m[i, i]), doc["uncertainty"]["camera"]["fu"], rel_tol=1e-9)
    back = sc.load_calibration(out)
    assert back.camera.fu == bench_cal.camera.fu


def test_a_bench_calibration_refuses_a_scan_with_poses(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict]
) -> None:
    with pytest.raises(sc.StripecalError, match="bench calibration"):
        sc.reconstruct_scan(bench_cal, twin[0] / "twin" / "scan")


def test_a_fixed_sensor_scan_is_reconstructed_in_the_camera_frame(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict], tmp_path: Path
) -> None:
    scan = tmp_path / "fixed"
    shutil.copytree(twin[0] / "twin" / "scan", scan)
    _strip_poses(scan / "scan.csv", 1)
    n_frames = sum(1 for _ in open(scan / "scan.csv")) - 1
    cloud = sc.reconstruct_scan(bench_cal, scan)
    assert len(cloud) > 100
    frames = cloud.frame
    assert frames.min() >= 0 and frames.max() < n_frames
    # In the camera frame every point lies on the TRUE laser plane (to the noise).
    lp = twin[2]["laser_plane"]
    dist = cloud.points @ np.array(lp["normal"]) - lp["d_mm"]
    assert np.median(np.abs(dist)) < 0.01
    ply = tmp_path / "fixed.ply"
    cloud.save(ply, ascii=True)
    header = ply.read_text().split("end_header")[0]
    assert "comment frame cam" in header
    assert "property double view" in header or "property float view" in header


def test_bad_bench_input_is_a_typed_error_naming_line_or_file(
    twin: Tuple[Path, Path, Dict], tmp_path: Path
) -> None:
    # A header with pose columns and a row with empty pose cells.
    ds = tmp_path / "mixed"
    shutil.copytree(twin[0] / "twin" / "calib", ds)
    lines = (ds / "views.csv").read_text().splitlines()
    cells = lines[3].split(",")
    lines[3] = ",".join(cells[:2] + [""] * (len(cells) - 2))
    (ds / "views.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(sc.StripecalError, match="line 4") as e:
        sc.load_dataset(ds)
    assert "bench dataset" in str(e.value)
    # A laser image of another size.
    other = tmp_path / "size"
    shutil.copytree(twin[1], other)
    laser = next(r[1] for r in csv.reader(open(other / "views.csv")) if r[1].endswith(".png"))
    img = sc.load_image(other / laser)
    sc.save_image(other / laser, np.ascontiguousarray(img[:, :-8]))
    with pytest.raises(sc.StripecalError) as e2:
        sc.calibrate(other)
    assert os.path.basename(laser) in str(e2.value) and "differ in size" in str(e2.value)


def _rotvec_matrix(w: np.ndarray) -> np.ndarray:
    th = float(np.linalg.norm(w))
    if th < 1e-15:
        return np.eye(3)
    k = w / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * kx + (1 - math.cos(th)) * kx @ kx


def _three_robot_views(bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict], tmp_path: Path) -> Tuple[Path, Path]:
    """Robot views 0, 5 and 10 of the twin, and the bench calibration saved."""
    src = twin[0] / "twin" / "calib"
    ds = tmp_path / "three"
    ds.mkdir()
    os.symlink(src / "images", ds / "images")
    shutil.copy(src / "rig.json", ds / "rig.json")
    lines = (src / "views.csv").read_text().splitlines()
    (ds / "views.csv").write_text("\n".join([lines[0], lines[1], lines[6], lines[11]]) + "\n")
    bench_json = tmp_path / "bench.json"
    bench_cal.save(bench_json)
    return ds, bench_json


def _hand_eye_errors(cal: sc.Calibration, truth: Dict) -> Tuple[float, np.ndarray]:
    x = _rotvec_matrix(np.array(truth["rotation_vector"]))
    h = np.asarray(cal.hand_cam)
    cos = (np.trace(h[:3, :3].T @ x) - 1) / 2
    return math.degrees(math.acos(min(1.0, cos))), h[:3, 3] - np.array(truth["translation_mm"])


def test_a_bench_calibration_as_a_prior_makes_three_robot_views_enough(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict], tmp_path: Path
) -> None:
    """Issue 17 item 3, the default `--from`: the bench's camera and plane enter with
    their covariance; 3 robot views give the hand-eye within 0.005 deg and 0.02 mm, the
    camera and plane sigmas are the bench's, and the hand-eye's sigma grows by what the
    bench's uncertainty contributes (against the same views with the blocks held)."""
    ds, bench_json = _three_robot_views(bench_cal, twin, tmp_path)
    prior = sc.calibrate(ds, from_calibration=bench_json, leave_one_out=False)
    held = sc.calibrate(ds, from_calibration=bench_json, fix=["camera", "laser_plane"], leave_one_out=False)
    deg, dt = _hand_eye_errors(prior, twin[2]["hand_cam"])
    assert deg <= 0.005 and np.linalg.norm(dt) <= 0.02
    assert prior.uncertainty["camera"]["fu"] == bench_cal.uncertainty["camera"]["fu"]
    assert prior.uncertainty["laser_plane"]["d_mm"] == bench_cal.uncertainty["laser_plane"]["d_mm"]
    sp = np.array(prior.uncertainty["hand_cam"]["translation_mm"])
    sh = np.array(held.uncertainty["hand_cam"]["translation_mm"])
    assert np.all(sp >= sh), (sp, sh)
    # What the bench's uncertainty contributes, on the rigid model: with the robot-pose
    # noise (the default since issue 38) these three rendered views' own part of their
    # pose error (1.15 x their pose precision) makes the hand-eye's sigma 3-18 times the
    # rigid model's, and the bench's share is lost in it (z: 0.0054 vs 0.0050 mm).
    rigid = dict(leave_one_out=False, robot_pose_noise=False)
    sp0 = np.array(sc.calibrate(ds, from_calibration=bench_json, **rigid).uncertainty["hand_cam"]["translation_mm"])
    sh0 = np.array(sc.calibrate(ds, from_calibration=bench_json, fix=["camera", "laser_plane"],
                                **rigid).uncertainty["hand_cam"]["translation_mm"])
    assert np.all(sp0 >= sh0) and np.any(sp0 > 1.2 * sh0), (sp0, sh0)
    # Honest: the translation error within 3 of the propagated sigmas.
    assert np.all(np.abs(dt) <= 3 * sp), (dt, sp)
    assert prior.extra["prior"]["blocks"] == ["camera", "laser_plane"]
    assert prior.covariance is not None
    names, m = prior.covariance
    i, j = names.index("hand_cam.translation_mm[0]"), names.index("camera.fu")
    assert m[i, j] != 0.0


def test_a_bench_calibration_held_makes_three_robot_views_enough(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict], tmp_path: Path
) -> None:
    """Issue 17 item 3 with `--fix camera,laser_plane`: the bench's camera and plane
    held, 3 robot views of the same twin give the hand-eye within 0.005 deg and 0.02 mm."""
    ds, bench_json = _three_robot_views(bench_cal, twin, tmp_path)
    cal = sc.calibrate(
        ds, from_calibration=bench_json, fix=["camera", "laser_plane"], leave_one_out=False
    )
    truth = twin[2]["hand_cam"]
    x = _rotvec_matrix(np.array(truth["rotation_vector"]))
    h = np.asarray(cal.hand_cam)
    cos = (np.trace(h[:3, :3].T @ x) - 1) / 2
    assert math.degrees(math.acos(min(1.0, cos))) <= 0.005
    assert np.linalg.norm(h[:3, 3] - np.array(truth["translation_mm"])) <= 0.02
    # The held blocks carry the bench's uncertainty.
    assert cal.uncertainty["camera"]["fu"] == bench_cal.uncertainty["camera"]["fu"]


def test_cli_and_report_on_the_bench(
    bench_cal: sc.Calibration, twin: Tuple[Path, Path, Dict], tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    from stripecal import cli, report

    out = tmp_path / "cal.json"
    assert cli.main(["calibrate", str(twin[1]), "-o", str(out)]) == 0
    # the leave-one-out table says how a bench view is predicted (no robot pose)
    printed = capsys.readouterr().out
    assert "leave-one-view-out (each view's board pose from its own target points" in printed
    assert "from its robot pose" not in printed
    doc = json.loads(out.read_text())
    assert "hand_cam" not in doc and doc["laser_plane"] is not None
    scan = tmp_path / "fixed"
    shutil.copytree(twin[0] / "twin" / "scan", scan)
    _strip_poses(scan / "scan.csv", 1)
    ply = tmp_path / "c.ply"
    assert cli.main(["reconstruct", str(out), str(scan), "-o", str(ply)]) == 0
    assert b"comment frame cam" in ply.read_bytes()[:2000]
    cal = sc.load_calibration(out)
    assert cal.is_bench
    html = report.write_report(tmp_path / "rep", cal).read_text()
    assert "X rotvec" not in html and "Z t" not in html
    assert "no robot pose" in html


def test_a_grid_without_markers_is_not_refused_on_the_bench(tmp_path: Path) -> None:
    """On the bench every view's labelling of a symmetric board is free (its own board
    pose): an unmarked grid calibrates with every view, to the truth."""
    cfg = sim.preset(
        "hp3-paper",
        seed=5,
        poses={"count": 8},
        imaging={"noise_gray": 1.0, "psf_sigma_px": 0.7},
        scan={"enabled": False},
    )
    cfg["board"]["markers"] = []
    sim.Twin(cfg).write(tmp_path / "twin")
    ds = tmp_path / "twin" / "calib"
    _strip_poses(ds / "views.csv", 2)
    assert json.loads((ds / "rig.json").read_text())["board"]["markers"] == []
    cal = sc.calibrate(ds)
    truth = json.loads((ds / "truth.json").read_text())
    assert cal.quality["views_used"] == 8
    assert abs(cal.camera.fu - truth["camera"]["fu"]) <= 1e-4 * truth["camera"]["fu"]
    plane = cal.laser_plane
    assert plane is not None and abs(plane[1] - truth["laser_plane"]["d_mm"]) <= 0.01
