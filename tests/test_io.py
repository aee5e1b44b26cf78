"""File round trips through the Python API and typed errors for malformed files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import stripecal

HOME = [0.0, 0.0, 0.0, 0.0, -90.0, 0.0]


def rigid(rotvec: list[float], t: list[float]) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = stripecal.rotvec_to_matrix(rotvec)
    m[:3, 3] = t
    return m


def camera() -> stripecal.Camera:
    return stripecal.Camera(768, 576, 1271.65, 1322.52, 346.14, 262.60, "radial2", [0.0002, -0.01, 0, 0, 0])


def calibration() -> stripecal.Calibration:
    return stripecal.Calibration(
        camera(),
        ([0.629, -0.0492, 0.7759], 79.87),
        rigid([-0.3087, 0.2362, 3.0369], [29.19, 5.37, 62.64]),
        rigid([0.01, -0.02, 0.5], [400.0, -20.0, 10.0]),
        robot=stripecal.Robot.hp3(),
        quality={"circle_rms_px": 0.05, "stripe_rms_px": 0.12, "views_used": 7},
        uncertainty={"camera": {"fu": 0.5, "fv": 0.6}, "laser_plane": {"normal": [1e-4, 2e-4, 3e-4], "d_mm": 0.01}},
        extra={"note": "made in a test", "n": 3},
    )


def assert_same_geometry(a: stripecal.Calibration | stripecal.Truth, b: stripecal.Calibration | stripecal.Truth) -> None:
    assert a.camera == b.camera
    np.testing.assert_allclose(a.laser_plane[0], b.laser_plane[0], atol=1e-12)
    assert a.laser_plane[1] == pytest.approx(b.laser_plane[1], abs=1e-12)
    np.testing.assert_allclose(a.hand_cam, b.hand_cam, atol=1e-9)
    np.testing.assert_allclose(a.base_board, b.base_board, atol=1e-9)
    assert a.robot == b.robot


def test_rig_round_trip(tmp_path: Path) -> None:
    board = stripecal.Board(6, 9, 10.0, 5.0, 7.0, markers=[(0, 0), (0, 1), (1, 0)], dark_circles=False)
    rig = stripecal.Rig((1024, 768), board, stripecal.Robot.hp3(), "opencv5", "rows")
    path = tmp_path / "rig.json"
    stripecal.save_rig(path, rig)
    back = stripecal.load_rig(path)
    assert back == rig
    assert back.camera_size == (1024, 768)
    assert back.board.dark_circles is False
    assert back.stripe_direction == "rows"
    assert json.loads(path.read_text())["format"] == "stripecal/rig@1"
    assert stripecal.Rig.from_json(rig.to_json()) == rig
    # flange-pose rigs have no robot
    no_robot = stripecal.Rig((640, 480), stripecal.Board.hp3_paper())
    no_robot.save(str(tmp_path / "rig2.json"))
    assert stripecal.load_rig(str(tmp_path / "rig2.json")) == no_robot


def test_calibration_round_trip(tmp_path: Path) -> None:
    calib = calibration()
    path = tmp_path / "calibration.json"
    stripecal.save_calibration(path, calib)
    back = stripecal.load_calibration(path)
    assert_same_geometry(back, calib)
    assert back.quality == {"circle_rms_px": 0.05, "target_rms_px": 0.05, "stripe_rms_px": 0.12,
                            "views_used": 7, "accepted_poor": False, "checks": []}
    assert back.uncertainty == calib.uncertainty
    assert back.extra["note"] == "made in a test"
    doc = json.loads(path.read_text())
    assert doc["format"] == "stripecal/calibration@1"
    assert doc["laser_plane"]["d_mm"] == pytest.approx(79.87 / np.linalg.norm([0.629, -0.0492, 0.7759]))
    assert_same_geometry(stripecal.Calibration.from_json(calib.to_json()), calib)
    calib.save(tmp_path / "again.json")
    assert_same_geometry(stripecal.load_calibration(tmp_path / "again.json"), calib)


def test_truth_round_trip(tmp_path: Path) -> None:
    truth = stripecal.Truth(
        camera(),
        ([0.0, -0.6, 0.8], 120.0),
        rigid([0.1, 0.2, 3.0], [30.0, 5.0, 60.0]),
        rigid([0.0, 0.0, 0.0], [450.0, 0.0, 0.0]),
        robot=stripecal.Robot.hp3(),
        sphere={"center_mm": [480.0, 10.0, 200.0], "diameter_mm": 25.4},
        working_range_mm=(80.0, 160.0),
        extra={"emitter_mm": [0.0, 40.0, 0.0]},
    )
    path = tmp_path / "truth.json"
    stripecal.save_truth(path, truth)
    back = stripecal.load_truth(path)
    assert_same_geometry(back, truth)
    assert back.sphere is not None
    np.testing.assert_array_equal(back.sphere["center_mm"], [480.0, 10.0, 200.0])
    assert back.sphere["diameter_mm"] == 25.4
    assert back.working_range_mm == (80.0, 160.0)
    assert back.extra["emitter_mm"] == [0.0, 40.0, 0.0]
    assert json.loads(path.read_text())["format"] == "stripecal/truth@1"


def test_sphere_fit_round_trip(tmp_path: Path) -> None:
    fit = stripecal.SphereFit(25.41, [1.0, 2.0, 3.0], 0.012, 1500, 12, extra={"diameter_sigma_mm": 0.003})
    path = tmp_path / "sphere.json"
    stripecal.save_sphere_fit(path, fit)
    back = stripecal.load_sphere_fit(path)
    assert back == fit
    assert json.loads(path.read_text())["points"] == 1500


@pytest.mark.parametrize("binary", [True, False])
def test_ply_round_trip(tmp_path: Path, binary: bool) -> None:
    rng = np.random.default_rng(3)
    points = rng.normal(size=(257, 3)) * 100.0
    props = {"view": np.repeat(np.arange(257 // 8 + 1), 8)[:257].astype(float), "u": rng.uniform(0, 768, 257)}
    path = tmp_path / "cloud.ply"
    stripecal.write_ply(path, points, props, binary=binary)
    cloud = stripecal.read_ply(path)
    np.testing.assert_array_equal(cloud["points"], points)
    assert list(cloud["properties"]) == ["view", "u"]
    np.testing.assert_array_equal(cloud["properties"]["view"], props["view"])
    np.testing.assert_array_equal(cloud["properties"]["u"], props["u"])
    head = path.read_bytes()[:200]
    assert (b"binary_little_endian" in head) == binary
    # no properties, empty cloud
    stripecal.write_ply(tmp_path / "empty.ply", np.zeros((0, 3)))
    empty = stripecal.read_ply(tmp_path / "empty.ply")
    assert empty["points"].shape == (0, 3) and empty["properties"] == {}


def test_ply_reader_accepts_float_properties(tmp_path: Path) -> None:
    path = tmp_path / "f.ply"
    header = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
    path.write_text(header + "1 2 3\n4.5 5 6\n")
    cloud = stripecal.read_ply(path)
    np.testing.assert_array_equal(cloud["points"], [[1, 2, 3], [4.5, 5, 6]])


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_image_round_trip(tmp_path: Path, dtype: type) -> None:
    rng = np.random.default_rng(5)
    img = rng.integers(0, np.iinfo(dtype).max, size=(37, 53), endpoint=True).astype(dtype)
    path = tmp_path / "img.png"
    stripecal.save_image(path, img)
    back = stripecal.load_image(path)
    assert back.dtype == dtype and back.shape == (37, 53)
    np.testing.assert_array_equal(back, img)
    # a non-contiguous view is written as what it shows
    stripecal.save_image(path, img[::2, ::3])
    np.testing.assert_array_equal(stripecal.load_image(path), img[::2, ::3])


def write_dataset(root: Path, rows: list[str], header: str = "board_image,laser_image,q1,q2,q3,q4,q5,q6", robot: bool = True) -> None:
    root.mkdir(parents=True, exist_ok=True)
    (root / "images").mkdir(exist_ok=True)
    rig = stripecal.Rig((64, 48), stripecal.Board.hp3_paper(), stripecal.Robot.hp3() if robot else None)
    rig.save(root / "rig.json")
    img = np.full((48, 64), 200, np.uint8)
    for i in range(3):
        stripecal.save_image(root / "images" / f"b{i}.png", img)
        stripecal.save_image(root / "images" / f"l{i}.png", img)
    (root / "views.csv").write_text(header + "\n" + "\n".join(rows) + "\n")


def test_dataset_with_joints(tmp_path: Path) -> None:
    write_dataset(
        tmp_path,
        [
            "images/b0.png,images/l0.png,0,0,0,0,-90,0",
            "images/b1.png,,1,2,3,4,-85,6",
            "images/b2.png,images/b2.png,-1,-2,-3,-4,-95,-6",
        ],
    )
    ds = stripecal.load_dataset(tmp_path)
    assert len(ds) == 3
    assert ds.rig.robot == stripecal.Robot.hp3()
    assert ds.lines == [2, 3, 4]
    assert ds.board_images[0] == str(tmp_path / "images/b0.png")
    assert ds.laser_images[1] is None
    assert ds.laser_images[2] == ds.board_images[2]
    assert ds.joints is not None and ds.joints.shape == (3, 6)
    assert ds.flange_poses is None
    np.testing.assert_array_equal(ds.joints[1], [1, 2, 3, 4, -85, 6])
    bh = ds.base_hand()
    assert bh.shape == (3, 4, 4)
    np.testing.assert_allclose(bh[0][:3, 3], [480.0, 0.0, 365.0], atol=1e-9)
    views = ds.views
    assert views[1]["laser_image"] is None and views[1]["flange_pose"] is None
    np.testing.assert_array_equal(views[0]["joints"], HOME)


def test_dataset_with_flange_poses(tmp_path: Path) -> None:
    write_dataset(
        tmp_path,
        [
            "images/b0.png,images/l0.png,480,0,365,0,1,0,0",
            "images/b1.png,images/l1.png,470,10,360,1,0,0,0",
        ],
        header="board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz",
        robot=False,
    )
    ds = stripecal.load_dataset(tmp_path)
    assert ds.joints is None and ds.rig.robot is None
    poses = ds.flange_poses
    assert poses is not None and poses.shape == (2, 4, 4)
    # qx = 1: a half turn about x
    np.testing.assert_allclose(poses[0], [[1, 0, 0, 480], [0, -1, 0, 0], [0, 0, -1, 365], [0, 0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(ds.base_hand(), poses)


def test_scan(tmp_path: Path) -> None:
    (tmp_path / "images").mkdir()
    for i in range(2):
        stripecal.save_image(tmp_path / "images" / f"s{i}.png", np.zeros((8, 8), np.uint8))
    (tmp_path / "scan.csv").write_text("image,q1,q2,q3,q4,q5,q6\nimages/s0.png,0,0,0,0,-90,0\nimages/s1.png,1,0,0,0,-90,0\n")
    scan = stripecal.load_scan(tmp_path, stripecal.Robot.hp3())
    assert len(scan) == 2 and scan.rig is None
    assert scan.images[1] == str(tmp_path / "images/s1.png")
    assert scan.joints is not None and scan.joints.shape == (2, 6)
    bh = scan.base_hand(stripecal.Robot.hp3())
    np.testing.assert_allclose(bh[0][:3, 3], [480.0, 0.0, 365.0], atol=1e-9)
    with pytest.raises(stripecal.InvalidInputError, match="robot"):
        scan.base_hand()


# ---- malformed files -------------------------------------------------------------------


def test_missing_file_is_file_not_found(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError) as info:
        stripecal.load_rig(tmp_path / "nope.json")
    assert info.value.filename == str(tmp_path / "nope.json")
    with pytest.raises(FileNotFoundError):
        stripecal.load_dataset(tmp_path / "no-such-dataset")


def test_rig_with_a_bad_key_names_file_and_key(tmp_path: Path) -> None:
    rig = stripecal.Rig((640, 480), stripecal.Board.hp3_paper(), stripecal.Robot.hp3())
    doc = json.loads(rig.to_json())
    doc["board"]["rows"] = "eight"
    path = tmp_path / "rig.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(stripecal.FormatError) as info:
        stripecal.load_rig(path)
    msg = str(info.value)
    assert "rig.json" in msg and "board.rows" in msg
    assert isinstance(info.value, ValueError) and isinstance(info.value, stripecal.StripecalError)


def test_rig_with_a_wrong_format_tag(tmp_path: Path) -> None:
    path = tmp_path / "rig.json"
    doc = json.loads(stripecal.Rig((640, 480), stripecal.Board.hp3_paper()).to_json())
    doc["format"] = "stripecal/rig@99"
    path.write_text(json.dumps(doc))
    with pytest.raises(stripecal.FormatError, match="format"):
        stripecal.load_rig(path)


def test_invalid_json_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "calibration.json"
    path.write_text('{"format": "stripecal/calibration@1", ')
    with pytest.raises(stripecal.FormatError, match="calibration.json"):
        stripecal.load_calibration(path)


def test_calibration_missing_key(tmp_path: Path) -> None:
    doc = json.loads(calibration().to_json())
    del doc["laser_plane"]["d_mm"]
    path = tmp_path / "calibration.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(stripecal.FormatError) as info:
        stripecal.load_calibration(path)
    assert "calibration.json" in str(info.value) and "laser_plane.d_mm" in str(info.value)


def test_views_csv_with_a_bad_number_names_file_and_line(tmp_path: Path) -> None:
    write_dataset(
        tmp_path,
        ["images/b0.png,images/l0.png,0,0,0,0,-90,0", "images/b1.png,images/l1.png,0,zero,0,0,-90,0"],
    )
    with pytest.raises(stripecal.FormatError) as info:
        stripecal.load_dataset(tmp_path)
    msg = str(info.value)
    assert "views.csv" in msg and "line 3" in msg and "q2" in msg


def test_views_csv_with_a_missing_image(tmp_path: Path) -> None:
    write_dataset(tmp_path, ["images/b0.png,images/l0.png,0,0,0,0,-90,0", "images/gone.png,,0,0,0,0,-90,0"])
    with pytest.raises(stripecal.FormatError) as info:
        stripecal.load_dataset(tmp_path)
    assert "views.csv" in str(info.value) and "line 3" in str(info.value) and "gone.png" in str(info.value)


def test_views_csv_with_the_wrong_joint_count(tmp_path: Path) -> None:
    write_dataset(tmp_path, ["images/b0.png,images/l0.png,0,0,0,0,-90"], header="board_image,laser_image,q1,q2,q3,q4,q5")
    with pytest.raises(stripecal.FormatError, match="views.csv"):
        stripecal.load_dataset(tmp_path)


def test_truncated_binary_ply(tmp_path: Path) -> None:
    path = tmp_path / "cloud.ply"
    stripecal.write_ply(path, np.ones((10, 3)))
    path.write_bytes(path.read_bytes()[:-5])
    with pytest.raises(stripecal.FormatError, match="cloud.ply"):
        stripecal.read_ply(path)


def test_ply_without_xyz(tmp_path: Path) -> None:
    path = tmp_path / "bad.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nend_header\n1\n")
    with pytest.raises(stripecal.FormatError, match="bad.ply"):
        stripecal.read_ply(path)


def test_corrupt_image(tmp_path: Path) -> None:
    path = tmp_path / "broken.png"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + b"\x00" * 40)
    with pytest.raises(stripecal.FormatError, match="broken.png"):
        stripecal.load_image(path)
