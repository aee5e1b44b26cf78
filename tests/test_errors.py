"""Bad input from Python gives TypeError / ValueError with a clear message, never a panic."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest

import stripecal

CAM = stripecal.Camera(640, 480, 800.0, 800.0, 320.0, 240.0)
ROBOT = stripecal.Robot.hp3()


def test_exception_hierarchy() -> None:
    assert issubclass(stripecal.StripecalError, Exception)
    for exc in (stripecal.FormatError, stripecal.InvalidInputError, stripecal.DegenerateError):
        assert issubclass(exc, stripecal.StripecalError) and issubclass(exc, ValueError)
    assert issubclass(stripecal.ConvergenceError, stripecal.StripecalError)
    assert issubclass(stripecal.ConvergenceError, RuntimeError)
    assert stripecal.FormatError.__module__ == "stripecal"
    assert stripecal.FormatError.__doc__


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((4, 3), dtype=complex),
        np.array([["a", "b", "c"]]),
        np.array([[object(), 1, 2]], dtype=object),
        np.zeros((4, 3), dtype=bool),
        None,
        "points",
        [[1.0, "x", 3.0]],
        {"x": 1},
    ],
    ids=["complex", "str", "object", "bool", "None", "string", "mixed-list", "dict"],
)
def test_wrong_dtype_is_type_error(bad: Any) -> None:
    with pytest.raises(TypeError, match="points"):
        CAM.project(bad)


@pytest.mark.parametrize(
    "shape", [(4, 2), (4, 4), (2,), (2, 3, 3), ()], ids=["Nx2", "Nx4", "2", "3d", "scalar"]
)
def test_wrong_shape_is_value_error(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=r"points must have shape \(3,\) or \(N, 3\)"):
        CAM.project(np.ones(shape))


def test_non_contiguous_and_foreign_layouts_are_read_correctly() -> None:
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-10, 10, 20), rng.uniform(-10, 10, 20), rng.uniform(50, 90, 20)])
    expected = CAM.project(pts)
    wide = np.zeros((20, 6))
    wide[:, ::2] = pts
    strided = wide[:, ::2]
    assert not strided.flags["C_CONTIGUOUS"]
    np.testing.assert_array_equal(CAM.project(strided), expected)
    np.testing.assert_array_equal(CAM.project(np.asfortranarray(pts)), expected)
    np.testing.assert_array_equal(CAM.project(pts[::-1])[::-1], expected)
    np.testing.assert_array_equal(CAM.project(pts.astype(">f8")), expected)
    np.testing.assert_array_equal(CAM.project(pts.tolist()), expected)
    ints = np.array([[1, 2, 100]], dtype=np.int32)
    np.testing.assert_array_equal(CAM.project(ints), CAM.project([[1.0, 2.0, 100.0]]))
    # results are fresh, writable float64 arrays
    out = CAM.project(pts)
    assert out.dtype == np.float64 and out.flags["C_CONTIGUOUS"] and out.flags["WRITEABLE"]


def test_robot_inputs() -> None:
    with pytest.raises(ValueError, match=r"\(6,\) or \(M, 6\)"):
        ROBOT.forward(np.zeros((3, 5)))
    with pytest.raises(TypeError):
        ROBOT.forward(np.zeros(6, dtype=complex))
    with pytest.raises(ValueError, match="q3"):
        ROBOT.forward([0, 0, np.inf, 0, 0, 0])
    with pytest.raises(ValueError, match=r"\(N, 4\)"):
        stripecal.Robot([[0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="no joints"):
        stripecal.Robot(np.zeros((0, 4)))
    not_rigid = np.eye(4)
    not_rigid[0, 0] = 2.0
    with pytest.raises(ValueError, match="t_base_hand|T_base_hand"):
        ROBOT.inverse(not_rigid, [0, 0, 0, 0, -90, 0])
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        ROBOT.inverse(np.eye(3), [0, 0, 0, 0, -90, 0])


def test_unreachable_pose_is_a_convergence_error() -> None:
    far = np.eye(4)
    far[:3, 3] = [5000.0, 0.0, 0.0]
    with pytest.raises(stripecal.ConvergenceError):
        ROBOT.inverse(far, [0, 0, 0, 0, -90, 0])


@pytest.mark.parametrize(
    "make",
    [
        lambda: stripecal.Camera(-1, 480, 800.0, 800.0, 320.0, 240.0),
        lambda: stripecal.Camera(640, 0, 800.0, 800.0, 320.0, 240.0),
        lambda: stripecal.Camera(640, 480, -800.0, 800.0, 320.0, 240.0),
        lambda: stripecal.Camera(640, 480, 800.0, 800.0, float("nan"), 240.0),
        lambda: stripecal.Camera(640, 480, 800.0, 800.0, 320.0, 240.0, "fisheye"),
        lambda: stripecal.Camera(640, 480, 800.0, 800.0, 320.0, 240.0, "radial1", [0.1, 0.2]),
        lambda: stripecal.Board(1, 5, 5.0, 2.0, 3.0),
        lambda: stripecal.Board(4, 5, 5.0, 5.0, 3.0),
        lambda: stripecal.Board(4, 5, 5.0, 2.0, 3.0, markers=[(9, 0)]),
        lambda: stripecal.Board(4, 5, 5.0, 2.0, 3.0, markers=[(-1, 0)]),
        lambda: stripecal.Board(4, 5, 5.0, 2.0, 3.0, kind="hexagons"),
        lambda: stripecal.Rig((0, 480), stripecal.Board.hp3_paper()),
        lambda: stripecal.Rig((640, 480), stripecal.Board.hp3_paper(), None, "radial1", "diagonal"),
        lambda: stripecal.Calibration(CAM, ([0, 0, 0], 1.0), np.eye(4), np.eye(4)),
        lambda: stripecal.Calibration(CAM, ([0, 0, 1], 1.0), np.eye(4), np.eye(4), quality={"rms": 1.0}),
        lambda: stripecal.Calibration(CAM, ([0, 0, 1], 1.0), np.eye(4), np.eye(4), extra={"x": float("nan")}),
        lambda: stripecal.Truth(CAM, ([0, 0, 1], 1.0), np.eye(4), np.eye(4), sphere={"diameter_mm": 3.0}),
        lambda: stripecal.matrix_to_rotvec(np.diag([1.0, 1.0, -1.0])),
        lambda: stripecal.rotvec_to_matrix([1.0, 2.0]),
    ],
)
def test_invalid_values_are_value_errors(make: Callable[[], object]) -> None:
    with pytest.raises(ValueError):
        make()


def test_laser_plane_must_be_a_pair() -> None:
    with pytest.raises(TypeError, match="laser_plane"):
        stripecal.Calibration(CAM, [0.0, 0.0, 1.0], np.eye(4), np.eye(4))  # type: ignore[arg-type]


def test_unstorable_json_is_type_error() -> None:
    with pytest.raises(TypeError, match="extra.x"):
        stripecal.Calibration(CAM, ([0, 0, 1], 1.0), np.eye(4), np.eye(4), extra={"x": object()})
    with pytest.raises(TypeError, match="keys must be str"):
        stripecal.Calibration(CAM, ([0, 0, 1], 1.0), np.eye(4), np.eye(4), uncertainty={1: 2})


def test_json_values_accept_numpy() -> None:
    c = stripecal.Calibration(
        CAM,
        (np.array([0, 0, 2.0]), 3.0),
        np.eye(4),
        np.eye(4),
        uncertainty={"a": np.array([1.0, 2.0]), "b": np.float32(0.5), "c": np.int64(3), "d": (True, None)},
    )
    assert c.uncertainty == {"a": [1.0, 2.0], "b": 0.5, "c": 3, "d": [True, None]}
    normal, d = c.laser_plane
    np.testing.assert_array_equal(normal, [0, 0, 1])
    assert d == 1.5


def test_save_image_rejects_other_dtypes_and_shapes(tmp_path: Path) -> None:
    with pytest.raises(TypeError, match="uint8 or uint16"):
        stripecal.save_image(tmp_path / "a.png", np.zeros((4, 4), np.float32))
    with pytest.raises(TypeError, match="numpy array"):
        stripecal.save_image(tmp_path / "a.png", [[1, 2], [3, 4]])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="2D"):
        stripecal.save_image(tmp_path / "a.png", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="2D"):
        stripecal.save_image(tmp_path / "a.png", np.zeros((0, 4), np.uint8))


def test_write_ply_checks_property_lengths(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"properties\[\"u\"\]"):
        stripecal.write_ply(tmp_path / "a.ply", np.zeros((5, 3)), {"u": np.zeros(4)})
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        stripecal.write_ply(tmp_path / "a.ply", np.zeros(3))


def test_paths_accept_str_and_pathlike(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        stripecal.load_calibration(str(tmp_path / "none.json"))
    with pytest.raises(FileNotFoundError):
        stripecal.load_calibration(tmp_path / "none.json")
    with pytest.raises(TypeError):
        stripecal.load_calibration(42)  # type: ignore[arg-type]


def test_fuzzed_inputs_never_panic() -> None:
    """Random shapes and dtypes: only TypeError / ValueError, never pyo3's PanicException."""
    rng = np.random.default_rng(11)
    calls: list[Callable[[Any], object]] = [
        CAM.project,
        CAM.unproject,
        CAM.project_jacobians,
        ROBOT.forward,
        ROBOT.jacobian,
        stripecal.rotvec_to_matrix,
        stripecal.matrix_to_rotvec,
        stripecal.nearest_rotation,
    ]
    dtypes = [np.float64, np.float32, np.int64, np.uint8, complex, bool, object]
    for _ in range(300):
        ndim = int(rng.integers(0, 4))
        shape = tuple(int(s) for s in rng.integers(0, 7, size=ndim))
        arr = (rng.normal(size=shape) * 100).astype(dtypes[int(rng.integers(len(dtypes)))])
        call = calls[int(rng.integers(len(calls)))]
        try:
            call(arr)
        except (TypeError, ValueError, stripecal.StripecalError):
            pass
