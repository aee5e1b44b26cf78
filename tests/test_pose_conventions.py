"""Flange poses in robot controllers' conventions (spec/DATASET.md, views.csv pose
columns): ``stripecal.pose_to_matrix`` / ``stripecal.matrix_to_pose`` against
independent numpy constructions and worked examples from the makers' documentation, the
twin writing views.csv / scan.csv in a convention, and malformed poses as typed errors.

Round trips compare ROTATION MATRICES (1e-12), never angles or quaternion signs: q and
-q are one rotation, and at gimbal lock only a sum or difference of two angles is
defined.
"""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path
from typing import Callable, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import stripecal
import stripecal.sim as sim
from stripecal.cli import main
from stripecal.types import SimConfig

F64 = npt.NDArray[np.float64]

# --------------------------------------------------------------------------- independent maths


def Rx(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def Ry(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def Rz(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rodrigues(r: npt.ArrayLike) -> F64:
    """R = I + sin(t) K + (1 - cos(t)) K^2, K the cross-product matrix of the unit axis."""
    v = np.asarray(r, dtype=np.float64)
    t = float(np.linalg.norm(v))
    if t == 0.0:
        return np.eye(3)
    k = v / t
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R: F64 = np.eye(3) + np.sin(t) * K + (1.0 - np.cos(t)) * (K @ K)
    return R


def quat_matrix(w: float, x: float, y: float, z: float) -> F64:
    """The unit quaternion w + xi + yj + zk as a rotation matrix (Hamilton)."""
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def rigid(R: F64, t_mm: npt.ArrayLike) -> F64:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t_mm
    return T


def assert_same_pose(a: F64, b: F64, tol: float = 1e-12) -> None:
    """Rotation matrices equal entry by entry, translations relative to their size."""
    assert np.abs(a[:3, :3] - b[:3, :3]).max() <= tol, (a, b)
    scale = max(float(np.linalg.norm(a[:3, 3])), float(np.linalg.norm(b[:3, 3])), 1.0)
    assert np.linalg.norm(a[:3, 3] - b[:3, 3]) / scale <= tol, (a, b)
    np.testing.assert_array_equal(a[3], [0.0, 0.0, 0.0, 1.0])


def random_rotation(rng: np.random.Generator) -> F64:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    return quat_matrix(*q)


# Each convention: its header, and how to build (values, expected T) from random numbers
# with the independent maths above.
def _kuka(rng: np.random.Generator) -> Tuple[List[float], F64]:
    a, b, c = rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, a, b, c], rigid(Rz(np.radians(a)) @ Ry(np.radians(b)) @ Rx(np.radians(c)), t)


def _fanuc(rng: np.random.Generator) -> Tuple[List[float], F64]:
    w, p, r = rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, w, p, r], rigid(Rz(np.radians(r)) @ Ry(np.radians(p)) @ Rx(np.radians(w)), t)


def _rotvec(rng: np.random.Generator) -> Tuple[List[float], F64]:
    r = rng.uniform(-4, 4, 3)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, *r], rigid(rodrigues(r), t)


def _rotvec_deg(rng: np.random.Generator) -> Tuple[List[float], F64]:
    r = rng.uniform(-4, 4, 3)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, *np.degrees(r)], rigid(rodrigues(r), t)


def _ur(rng: np.random.Generator) -> Tuple[List[float], F64]:
    r = rng.uniform(-4, 4, 3)
    t = rng.uniform(-1.5, 1.5, 3)
    return [*t, *r], rigid(rodrigues(r), t * 1000.0)


def _quaternion(rng: np.random.Generator) -> Tuple[List[float], F64]:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, *q], rigid(quat_matrix(*q), t)


def _ros(rng: np.random.Generator) -> Tuple[List[float], F64]:
    w, x, y, z = rng.normal(size=4) / 1.0
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    t = rng.uniform(-1.5, 1.5, 3)
    return [*t, x, y, z, w], rigid(quat_matrix(w, x, y, z), t * 1000.0)


def _matrix(rng: np.random.Generator) -> Tuple[List[float], F64]:
    R = random_rotation(rng)
    t = rng.uniform(-1500, 1500, 3)
    return [*t, *R.ravel()], rigid(R, t)


CONVENTIONS: Dict[str, Tuple[str, Callable[[np.random.Generator], Tuple[List[float], F64]]]] = {
    "kuka": ("x_mm,y_mm,z_mm,a_deg,b_deg,c_deg", _kuka),
    "fanuc": ("x_mm,y_mm,z_mm,w_deg,p_deg,r_deg", _fanuc),
    "rotvec": ("x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad", _rotvec),
    "rotvec_deg": ("x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg", _rotvec_deg),
    "ur": ("x_m,y_m,z_m,rx_rad,ry_rad,rz_rad", _ur),
    "quaternion": ("x_mm,y_mm,z_mm,qw,qx,qy,qz", _quaternion),
    "ros": ("x_m,y_m,z_m,qx,qy,qz,qw", _ros),
    "matrix": ("x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33", _matrix),
}


# --------------------------------------------------------------------------- conventions


@pytest.mark.parametrize("name", list(CONVENTIONS))
def test_convention_matches_independent_construction_and_round_trips(name: str) -> None:
    header, make = CONVENTIONS[name]
    columns = header.split(",")
    rng = np.random.default_rng(sum(map(ord, name)))
    for _ in range(300):
        values, want = make(rng)
        # the shorthand, the header string and the column list name the same columns
        for conv in (name, header, columns):
            assert_same_pose(stripecal.pose_to_matrix(values, conv), want)
        # and any order of them
        perm = rng.permutation(len(columns))
        shuffled = [columns[i] for i in perm]
        assert_same_pose(stripecal.pose_to_matrix([values[i] for i in perm], shuffled), want)
        # round trip: matrix -> values -> matrix
        back = stripecal.matrix_to_pose(want, name)
        assert back.shape == (len(columns),) and back.dtype == np.float64
        assert_same_pose(stripecal.pose_to_matrix(back, name), want)
        back = stripecal.matrix_to_pose(want, shuffled)
        assert_same_pose(stripecal.pose_to_matrix(back, shuffled), want)


@pytest.mark.parametrize("name", list(CONVENTIONS))
def test_rows_of_poses(name: str) -> None:
    header, make = CONVENTIONS[name]
    rng = np.random.default_rng(1)
    rows = [make(rng) for _ in range(5)]
    values = np.array([v for v, _ in rows])
    T = stripecal.pose_to_matrix(values, name)
    assert T.shape == (5, 4, 4)
    for Ti, (_, want) in zip(T, rows):
        assert_same_pose(Ti, want)
    back = stripecal.matrix_to_pose(T, name)
    assert back.shape == (5, len(header.split(",")))
    for Ti, b in zip(T, back):
        assert_same_pose(stripecal.pose_to_matrix(b, name), Ti)


@pytest.mark.parametrize("middle", [90.0, -90.0, 90.0 - 1e-9, -90.0 + 1e-7, 89.9999])
@pytest.mark.parametrize("name", ["kuka", "fanuc"])
def test_euler_angles_at_gimbal_lock_round_trip_as_matrices(name: str, middle: float) -> None:
    """B = +-90 (KUKA) and P = +-90 (Fanuc): only A - C (or A + C) is defined there, so
    the angles need not come back, the matrix must."""
    rng = np.random.default_rng(3)
    for _ in range(100):
        first, last = rng.uniform(-180, 180, 2)
        t = rng.uniform(-900, 900, 3)
        if name == "kuka":  # [A, B, C]: R = Rz(A) Ry(B) Rx(C)
            R = Rz(np.radians(first)) @ Ry(np.radians(middle)) @ Rx(np.radians(last))
        else:  # [W, P, R]: R = Rz(R) Ry(P) Rx(W)
            R = Rz(np.radians(last)) @ Ry(np.radians(middle)) @ Rx(np.radians(first))
        want = rigid(R, t)
        T = stripecal.pose_to_matrix([*t, first, middle, last], name)
        assert_same_pose(T, want)
        back = stripecal.matrix_to_pose(T, name)
        assert abs(back[4]) <= 90.0 + 1e-12
        assert_same_pose(stripecal.pose_to_matrix(back, name), want)


@pytest.mark.parametrize("angle", [np.pi, np.pi - 1e-12, np.pi - 1e-8, np.pi - 1e-4, 1e-10, 0.0])
@pytest.mark.parametrize("name", ["rotvec", "rotvec_deg", "ur"])
def test_rotation_vectors_near_a_half_turn(name: str, angle: float) -> None:
    rng = np.random.default_rng(4)
    scale = 180.0 / np.pi if name == "rotvec_deg" else 1.0
    for _ in range(100):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        r = axis * angle
        want = rigid(rodrigues(r), [100.0, -200.0, 300.0])
        t = np.array([0.1, -0.2, 0.3]) if name == "ur" else np.array([100.0, -200.0, 300.0])
        T = stripecal.pose_to_matrix([*t, *(r * scale)], name)
        assert_same_pose(T, want)
        back = stripecal.matrix_to_pose(T, name)
        assert np.linalg.norm(back[3:]) / scale <= np.pi + 1e-12
        assert_same_pose(stripecal.pose_to_matrix(back, name), want)


def test_quaternion_columns_in_every_order() -> None:
    rng = np.random.default_rng(5)
    names = ["qw", "qx", "qy", "qz"]
    for _ in range(20):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        want = rigid(quat_matrix(*q), [1.0, 2.0, 3.0])
        for perm in itertools.permutations(range(4)):
            cols = ["x_mm", "y_mm", "z_mm", *[names[i] for i in perm]]
            vals = [1.0, 2.0, 3.0, *[q[i] for i in perm]]
            assert_same_pose(stripecal.pose_to_matrix(vals, cols), want)
            # -q is the same rotation
            assert_same_pose(stripecal.pose_to_matrix([1.0, 2.0, 3.0, *[-q[i] for i in perm]], cols), want)
            np.testing.assert_array_equal(stripecal.matrix_to_pose(want, cols)[3:],
                                          stripecal.matrix_to_pose(want, "quaternion")[3:][list(perm)])


# --------------------------------------------------------------------------- worked examples


def test_universal_robots_worked_examples() -> None:
    """Universal Robots, The URScript Programming Language (script manual), functions
    ``rpy2rotvec`` and ``rotvec2rpy``; both define "Rrpy = Rz(yaw)Ry(pitch)Rx(roll)" and
    give one example each:

    - https://www.universal-robots.com/manuals/EN/HTML/SW5_21/Content/prod-scriptmanual/all_scripts/rpy2rotvec_rpy_vector.htm
      ``rpy2rotvec([3.14,1.57,0])`` "Returns [2.22153, 0.00177, -2.21976]";
    - https://www.universal-robots.com/manuals/EN/HTML/SW10_7/Content/prod-scriptmanual/G5/rotvec2rpy_rotation_vector.htm
      ``rotvec2rpy([3.14,1.57,0])`` "Returns [-2.80856, -0.16202, 0.9]".

    The manual prints 5 decimals, hence the 1e-5-level tolerances. A UR controller's TCP
    pose is (x, y, z) in metres and this rotation vector in radians: the ``ur`` columns.
    UR's RPY product Rz(yaw) Ry(pitch) Rx(roll) is the contract's Fanuc W, P, R product
    with W = roll, P = pitch, R = yaw, so the second example also checks ``fanuc``.
    """
    rpy = np.array([3.14, 1.57, 0.0])
    R_rpy = Rz(rpy[2]) @ Ry(rpy[1]) @ Rx(rpy[0])
    T = stripecal.pose_to_matrix([0.4, -0.1, 0.3, 2.22153, 0.00177, -2.21976], "ur")
    assert np.abs(T[:3, :3] - R_rpy).max() < 2e-5
    np.testing.assert_allclose(T[:3, 3], [400.0, -100.0, 300.0], rtol=1e-15)
    # and back: our rotation vector of that RPY is the manual's, to its 5 decimals
    back = stripecal.matrix_to_pose(rigid(R_rpy, [400.0, -100.0, 300.0]), "ur")
    np.testing.assert_allclose(back[3:], [2.22153, 0.00177, -2.21976], atol=6e-6)
    np.testing.assert_allclose(back[:3], [0.4, -0.1, 0.3], rtol=1e-15)
    # rotvec2rpy([3.14, 1.57, 0]) = [roll, pitch, yaw] = [-2.80856, -0.16202, 0.9]
    T = stripecal.pose_to_matrix([0.0, 0.0, 0.0, 3.14, 1.57, 0.0], "ur")
    w, p, r = np.radians(stripecal.matrix_to_pose(T, "fanuc")[3:])
    np.testing.assert_allclose([w, p, r], [-2.80856, -0.16202, 0.9], atol=1e-5)
    # the same in degrees (rx_deg..)
    T_deg = stripecal.pose_to_matrix([0.0, 0.0, 0.0, *np.degrees([3.14, 1.57, 0.0])], "rotvec_deg")
    assert_same_pose(T_deg, T, 1e-15)


def test_ros_quaternion_order_worked_examples() -> None:
    """ROS orders a quaternion x, y, z, w and lengths are metres:

    - REP 103, "Standard Units of Measure and Coordinate Conventions"
      (https://ros.org/reps/rep-0103.html), section Units: length in metres;
    - geometry_msgs/msg/Quaternion (https://docs.ros.org/en/jazzy/p/geometry_msgs/msg/Quaternion.html):
      ``float64 x 0, float64 y 0, float64 z 0, float64 w 1``: the defaults are no rotation;
    - ROS 2 tutorial "Quaternion fundamentals"
      (https://docs.ros.org/en/jazzy/Tutorials/Intermediate/Tf2/Quaternion-Fundamentals.html),
      "Components of a quaternion": "(x, y, z, w). In ROS 2, w is last"; "the unit
      quaternion that yields no rotation about the x/y/z axes is (0, 0, 0, 1)"; section
      "Quaternion types in ROS 2": ``quat_tf = [0.0, 1.0, 0.0, 0.0]`` becomes
      ``Quaternion(x=quat_tf[0], y=quat_tf[1], z=quat_tf[2], w=quat_tf[3])``.

    By hand: x = 0, y = 1, z = 0, w = 0 is a half turn about y (R = 2 v v^T - I for w = 0,
    v = (0, 1, 0)): diag(-1, 1, -1). Read as w, x, y, z it would be a half turn about x,
    diag(1, -1, -1): the order matters, and the column names settle it.
    """
    pose = [0.5, 0.25, -0.125]  # geometry_msgs/Point, metres
    T = stripecal.pose_to_matrix([*pose, 0.0, 0.0, 0.0, 1.0], "ros")
    np.testing.assert_array_equal(T, rigid(np.eye(3), [500.0, 250.0, -125.0]))
    T = stripecal.pose_to_matrix([*pose, 0.0, 1.0, 0.0, 0.0], "x_m,y_m,z_m,qx,qy,qz,qw")
    assert_same_pose(T, rigid(np.diag([-1.0, 1.0, -1.0]), [500.0, 250.0, -125.0]), 1e-15)
    T = stripecal.pose_to_matrix([*pose, 0.0, 1.0, 0.0, 0.0], "x_m,y_m,z_m,qw,qx,qy,qz")
    assert_same_pose(T, rigid(np.diag([1.0, -1.0, -1.0]), [500.0, 250.0, -125.0]), 1e-15)
    # the order ROS writes comes back
    np.testing.assert_array_equal(stripecal.matrix_to_pose(rigid(np.diag([-1.0, 1.0, -1.0]), [500, 250, -125]), "ros"),
                                  [0.5, 0.25, -0.125, 0.0, 1.0, 0.0, 0.0])


def test_kuka_abc_worked_examples() -> None:
    """KUKA A, B, C: R = Rz(A) Ry(B) Rx(C) (contract). I found no published numeric ABC ->
    matrix example from KUKA itself. What is checked:

    - Roboception's "KUKA XYZ-ABC format" page of the rc_visard manual
      (https://docs.baslerweb.com/stereovisard/rc_cube/de/pose_format_kuka, section
      "Umrechnung von KUKA-ABC in Quaternionen" / "Conversion from KUKA-ABC to
      quaternion"): "r_z(A) r_y(B) r_x(C)" and the half-angle formulas for the quaternion
      (x, y, z, w), an independent construction, checked on random angles;
    - hand-derived cases: A = 90, B = 0, C = 180 is Rz(90) Rx(180) = [[0, 1, 0],
      [1, 0, 0], [0, 0, -1]] (a tool pointing down, its x along base y); the KRL target
      ``PTP {X 280, Y 0, Z -10, A 30, B 90, C 0}`` of javakuka.org's "Hello, ABC!"
      (http://javakuka.org/26.html) is at the gimbal lock: with B = 90,
      R = [[0, sin(C - A), cos(C - A)], [0, cos(C - A), -sin(C - A)], [-1, 0, 0]], so
      A = 30, C = 0 gives [[0, -1/2, sqrt(3)/2], [0, sqrt(3)/2, 1/2], [-1, 0, 0]], and
      A = 40, C = 10 is the same rotation.
    """
    rng = np.random.default_rng(6)
    for _ in range(200):
        a, b, c = np.radians([rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180)])
        ca, sa, cb, sb, cc, sc = np.cos(a / 2), np.sin(a / 2), np.cos(b / 2), np.sin(b / 2), np.cos(c / 2), np.sin(c / 2)
        x = ca * cb * sc - sa * sb * cc
        y = ca * sb * cc + sa * cb * sc
        z = sa * cb * cc - ca * sb * sc
        w = ca * cb * cc + sa * sb * sc
        T = stripecal.pose_to_matrix([0, 0, 0, *np.degrees([a, b, c])], "kuka")
        assert np.abs(T[:3, :3] - quat_matrix(w, x, y, z)).max() < 1e-12
    T = stripecal.pose_to_matrix([0.0, 0.0, 0.0, 90.0, 0.0, 180.0], "kuka")
    assert np.abs(T[:3, :3] - np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1]])).max() < 1e-15
    h = np.sqrt(3.0) / 2.0
    want = rigid(np.array([[0.0, -0.5, h], [0.0, h, 0.5], [-1.0, 0.0, 0.0]]), [280.0, 0.0, -10.0])
    assert_same_pose(stripecal.pose_to_matrix([280.0, 0.0, -10.0, 30.0, 90.0, 0.0], "kuka"), want, 1e-15)
    assert_same_pose(stripecal.pose_to_matrix([280.0, 0.0, -10.0, 40.0, 90.0, 10.0], "kuka"), want, 1e-15)
    assert_same_pose(stripecal.pose_to_matrix(stripecal.matrix_to_pose(want, "kuka"), "kuka"), want)


def test_fanuc_wpr_worked_examples() -> None:
    """Fanuc W, P, R: rotations about the fixed x, y, z axes in that order,
    R = Rz(R) Ry(P) Rx(W) (contract). I found no published numeric WPR -> matrix example
    from Fanuc itself. What is checked:

    - Roboception's "FANUC XYZ-WPR format" page of the rc_visard manual
      (https://doc.rc-visard.com/v22.01/en/pose_format_fanuc.html): "The rotation order is
      x-y-z and computed by rz(R)ry(P)rx(W)", with the half-angle quaternion formulas, an
      independent construction checked on random angles;
    - Universal Robots' rotvec2rpy example (test_universal_robots_worked_examples): the
      same product with published numbers;
    - hand-derived cases: W = 180, P = 0, R = 0 is a half turn about x, diag(1, -1, -1)
      (the hand's z pointing down, as a Fanuc tool usually is); W = 180, P = 0, R = 90 is
      Rz(90) diag(1, -1, -1) = [[0, 1, 0], [1, 0, 0], [0, 0, -1]].
    """
    rng = np.random.default_rng(7)
    for _ in range(200):
        W, P, R = np.radians([rng.uniform(-180, 180), rng.uniform(-90, 90), rng.uniform(-180, 180)])
        cr, sr, cp, sp, cw, sw = np.cos(R / 2), np.sin(R / 2), np.cos(P / 2), np.sin(P / 2), np.cos(W / 2), np.sin(W / 2)
        x = cr * cp * sw - sr * sp * cw
        y = cr * sp * cw + sr * cp * sw
        z = sr * cp * cw - cr * sp * sw
        w = cr * cp * cw + sr * sp * sw
        T = stripecal.pose_to_matrix([0, 0, 0, *np.degrees([W, P, R])], "fanuc")
        assert np.abs(T[:3, :3] - quat_matrix(w, x, y, z)).max() < 1e-12
    T = stripecal.pose_to_matrix([500.0, 0.0, 300.0, 180.0, 0.0, 0.0], "fanuc")
    assert_same_pose(T, rigid(np.diag([1.0, -1.0, -1.0]), [500.0, 0.0, 300.0]), 1e-15)
    T = stripecal.pose_to_matrix([500.0, 0.0, 300.0, 180.0, 0.0, 90.0], "fanuc")
    assert_same_pose(T, rigid(np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]), [500.0, 0.0, 300.0]), 1e-15)


def test_matrix_worked_example() -> None:
    """Row by row: r11 r12 r13 is the first row. By hand, a quarter turn about z maps x to
    y: R = [[0, -1, 0], [1, 0, 0], [0, 0, 1]] (its first column is the hand's x axis, base
    y). Reading the same nine numbers column by column would give the inverse rotation."""
    v = [10.0, 20.0, 30.0, 0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    T = stripecal.pose_to_matrix(v, "matrix")
    assert_same_pose(T, rigid(Rz(np.pi / 2), [10.0, 20.0, 30.0]), 1e-15)
    np.testing.assert_allclose(T[:3, :3] @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


# --------------------------------------------------------------------------- API errors


def test_api_errors_are_typed() -> None:
    with pytest.raises(stripecal.InvalidInputError, match="norm 0.5"):
        stripecal.pose_to_matrix([0, 0, 0, 0, 0, 0, 0.5], "ros")
    with pytest.raises(stripecal.InvalidInputError, match=r"values\[1\]: .*norm 2"):
        stripecal.pose_to_matrix([[0, 0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 0, 2]], "ros")
    with pytest.raises(stripecal.InvalidInputError, match="not a rotation.*det = -1"):
        stripecal.pose_to_matrix([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, -1], "matrix")
    with pytest.raises(stripecal.InvalidInputError, match="unknown pose convention 'abb'|unknown pose convention \"abb\""):
        stripecal.pose_to_matrix([0] * 6, "abb")
    with pytest.raises(stripecal.InvalidInputError, match="2 rotation conventions"):
        stripecal.pose_to_matrix([0] * 9, "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg,w_deg,p_deg,r_deg")
    with pytest.raises(stripecal.InvalidInputError, match="header has qw, qx, qy but not qz"):
        stripecal.pose_to_matrix([0] * 6, ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy"])
    with pytest.raises(stripecal.InvalidInputError, match=r"shape \(7,\) or \(M, 7\)"):
        stripecal.pose_to_matrix([0] * 6, "ros")
    with pytest.raises(stripecal.InvalidInputError, match="not a finite number"):
        stripecal.pose_to_matrix([0, 0, np.nan, 0, 0, 0, 1], "ros")
    with pytest.raises(TypeError, match="convention must be a str or a sequence of str"):
        stripecal.pose_to_matrix([0] * 7, 5)  # type: ignore[arg-type]
    with pytest.raises(stripecal.InvalidInputError, match=r"shape \(4, 4\) or \(M, 4, 4\)"):
        stripecal.matrix_to_pose(np.eye(3), "ros")
    with pytest.raises(stripecal.InvalidInputError, match="not a rotation"):
        stripecal.matrix_to_pose(np.diag([1.0, 1.0, -1.0, 1.0]), "ros")


# --------------------------------------------------------------------------- the twin


def _small(pose_columns: Optional[str]) -> SimConfig:
    over: SimConfig = {"poses": {"count": 4}, "scan": {"max_frames": 2}, "seed": 2}
    if pose_columns is not None:
        over["pose_columns"] = pose_columns
    return sim.preset("hp3-paper", over)


@pytest.fixture(scope="module")
def twins(tmp_path_factory: pytest.TempPathFactory) -> Dict[str, Path]:
    """The same small twin written three times: joint readings, ROS (metres, x,y,z,w)
    and KUKA A, B, C."""
    root = tmp_path_factory.mktemp("pose_twins")
    out = {}
    for key, cols in [("joints", None), ("ros", "ros"), ("kuka", "kuka")]:
        sim.Twin(_small(cols)).write(root / key)
        out[key] = root / key
    return out


def test_twin_with_pose_columns_gives_the_same_base_hand(twins: Dict[str, Path]) -> None:
    ref = stripecal.load_dataset(twins["joints"] / "calib")
    ref_scan = stripecal.load_scan(twins["joints"] / "scan")
    assert ref.joints is not None and ref.flange_poses is None
    headers = {"ros": "x_m,y_m,z_m,qx,qy,qz,qw", "kuka": "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg"}
    for key, header in headers.items():
        views = (twins[key] / "calib" / "views.csv").read_text().splitlines()
        assert views[0] == f"board_image,laser_image,{header}"
        assert (twins[key] / "scan" / "scan.csv").read_text().splitlines()[0] == f"image,{header}"
        ds = stripecal.load_dataset(twins[key] / "calib")
        assert ds.joints is None and ds.flange_poses is not None
        assert ds.rig.robot is not None  # rig.json still carries the (nominal) robot
        scan = stripecal.load_scan(twins[key] / "scan")
        for a, b in [(ds.base_hand(), ref.base_hand()), (scan.base_hand(), ref_scan.base_hand())]:
            assert a.shape == b.shape
            assert np.abs(a[:, :3, :3] - b[:, :3, :3]).max() <= 1e-12
            assert np.abs(a[:, :3, 3] - b[:, :3, 3]).max() <= 1e-9
        # the images are the same: only the pose columns differ
        for name in ["view_000_board.png", "view_003_laser.png"]:
            assert (twins[key] / "calib" / "images" / name).read_bytes() == \
                (twins["joints"] / "calib" / "images" / name).read_bytes()


def test_cli_calibrates_a_twin_with_pose_columns(twins: Dict[str, Path], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """`stripecal simulate --set pose_columns=ur` (Universal Robots: metres and a rotation
    vector) then `stripecal calibrate`: the same result as from the joint readings."""
    assert main(["simulate", str(tmp_path / "ur"), "--seed", "2", "--poses", "4", "--no-scan",
                 "--set", "pose_columns=ur"]) == 0
    calib = tmp_path / "ur" / "calib"
    assert (calib / "views.csv").read_text().splitlines()[0] == \
        "board_image,laser_image,x_m,y_m,z_m,rx_rad,ry_rad,rz_rad"
    out = tmp_path / "cal.json"
    assert main(["calibrate", str(calib), "-o", str(out)]) == 0
    capsys.readouterr()
    cal = stripecal.load_calibration(out)
    truth = stripecal.load_truth(calib / "truth.json")
    assert cal.quality["views_used"] == 4
    assert np.linalg.norm(cal.hand_cam[:3, 3] - truth.hand_cam[:3, 3]) < 1.0
    # the same twin's joint readings (base_hand equal to ~1e-13 mm) calibrate the same
    ref = stripecal.calibrate(twins["joints"] / "calib")
    np.testing.assert_allclose(cal.hand_cam, ref.hand_cam, atol=1e-6)


# --------------------------------------------------------------------------- malformed files


def _dataset_with(tmp_path: Path, twins: Dict[str, Path], views_csv: str) -> Path:
    d = tmp_path / "ds"
    shutil.copytree(twins["ros"] / "calib", d)
    (d / "views.csv").write_text(views_csv)
    return d


@pytest.mark.parametrize(
    "header,rows,match",
    [
        ("x_m,y_m,z_m,qx,qy,qz,qw", ["0.4,0,0.3,0,0,0,1", "0.4,0,0.3,0,0,0,0.5"], r"line 3.*norm 0\.5"),
        ("x_mm,y_mm,z_mm,qw,qx,qy,qz,a_deg,b_deg,c_deg", ["1,2,3,1,0,0,0,0,0,0"],
         r"line 1: header has 2 rotation conventions: qw, qx, qy, qz \(a unit quaternion\) and a_deg, b_deg, c_deg"),
        ("x_mm,y_mm,z_mm,qw,qx,qy", ["1,2,3,1,0,0"], r"line 1: header has qw, qx, qy but not qz"),
        ("x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33",
         ["1,2,3,1,0,0,0,1,0,0,0,1", "1,2,3,1,0,0,0,1,0,0,0,1", "1,2,3,1,0,0,0,1,0,0,0,-1"], r"line 4.*not a rotation.*det = -1"),
        ("x_mm,y_mm,z_mm,x_m,y_m,z_m,qw,qx,qy,qz", ["1,2,3,1,2,3,1,0,0,0"], r"line 1: .*millimetres.*metres"),
        ("x_mm,y_mm,z_mm,qw,qx,qy,qz,qz", ["1,2,3,1,0,0,0,0"], r"line 1: column `qz` appears twice"),
        ("x_mm,y_mm,z_mm,a_deg,b_deg,c_deg", ["1,2,3,0,,0"], r"line 2, column b_deg"),
    ],
    ids=["non-unit-quaternion", "two-rotations", "missing-column", "reflection", "mm-and-m", "duplicate", "empty-cell"],
)
def test_malformed_views_csv_is_a_format_error_naming_the_line(
    tmp_path: Path, twins: Dict[str, Path], header: str, rows: List[str], match: str
) -> None:
    text = f"board_image,laser_image,{header}\n" + "".join(
        f"images/view_{i:03}_board.png,images/view_{i:03}_laser.png,{r}\n" for i, r in enumerate(rows)
    )
    d = _dataset_with(tmp_path, twins, text)
    with pytest.raises(stripecal.FormatError, match=match) as e:
        stripecal.load_dataset(d)
    assert "views.csv" in str(e.value)
    with pytest.raises(stripecal.FormatError, match=match):
        stripecal.calibrate(d)


def test_malformed_scan_csv_is_a_format_error_naming_the_line(tmp_path: Path, twins: Dict[str, Path]) -> None:
    d = tmp_path / "scan"
    shutil.copytree(twins["kuka"] / "scan", d)
    lines = (d / "scan.csv").read_text().splitlines()
    lines[0] = lines[0] + ",qw"
    lines[2] = lines[2] + ",1"
    (d / "scan.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(stripecal.FormatError, match=r"scan\.csv: line 1: header has 2 rotation conventions"):
        stripecal.load_scan(d)
