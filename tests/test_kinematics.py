"""Forward kinematics of the Robot binding against the DH convention written out in numpy."""

from __future__ import annotations

import numpy as np
import pytest

import stripecal

HOME = [0.0, 0.0, 0.0, 0.0, -90.0, 0.0]


def dh_forward(dh: np.ndarray, q_deg: np.ndarray) -> np.ndarray:
    """T_base_hand = A_1 ... A_N with A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha), theta = q - theta0."""
    t = np.eye(4)
    for (theta0, alpha, a, d), q in zip(dh, q_deg):
        th = np.radians(q - theta0)
        al = np.radians(alpha)
        rz = np.array(
            [[np.cos(th), -np.sin(th), 0, 0], [np.sin(th), np.cos(th), 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
        )
        tz = np.eye(4)
        tz[2, 3] = d
        tx = np.eye(4)
        tx[0, 3] = a
        rx = np.array(
            [[1, 0, 0, 0], [0, np.cos(al), -np.sin(al), 0], [0, np.sin(al), np.cos(al), 0], [0, 0, 0, 1]]
        )
        t = t @ rz @ tz @ tx @ rx
    return t


def test_hp3_home_pose() -> None:
    robot = stripecal.Robot.hp3()
    assert robot.name == "MOTOMAN HP3"
    assert robot.dof == 6
    t = robot.forward(HOME)
    assert t.shape == (4, 4)
    np.testing.assert_allclose(t[:3, 3], [480.0, 0.0, 365.0], atol=1e-9)
    # flange z axis along base -z
    np.testing.assert_allclose(t[:3, 2], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(t[3], [0, 0, 0, 1])


def test_hp3_dh_table() -> None:
    dh = stripecal.Robot.hp3().dh
    assert dh.shape == (6, 4)
    assert dh.dtype == np.float64
    np.testing.assert_array_equal(dh[0], [0.0, -90.0, 100.0, 0.0])
    np.testing.assert_array_equal(dh[3], [0.0, 90.0, 0.0, -380.0])


def test_forward_matches_numpy_dh_for_random_joints() -> None:
    robot = stripecal.Robot.hp3()
    rng = np.random.default_rng(20240611)
    qs = rng.uniform(-170.0, 170.0, size=(200, 6))
    batch = robot.forward(qs)
    assert batch.shape == (200, 4, 4)
    for q, tb in zip(qs, batch):
        expected = dh_forward(robot.dh, q)
        single = robot.forward(q)
        np.testing.assert_allclose(single[:3, 3], expected[:3, 3], rtol=0, atol=1e-9)
        np.testing.assert_allclose(single[:3, :3], expected[:3, :3], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(single, tb)


def test_forward_of_a_custom_robot_and_list_input() -> None:
    rows = [(10.0, -90.0, 50.0, 300.0), (-5.0, 0.0, 250.0, 0.0), (0.0, 90.0, 0.0, 20.0)]
    robot = stripecal.Robot(rows, name="three")
    assert robot == stripecal.Robot(np.array(rows), name="three")
    assert robot.name == "three" and robot.dof == 3
    rng = np.random.default_rng(7)
    for q in rng.uniform(-180, 180, size=(50, 3)):
        np.testing.assert_allclose(
            robot.forward(list(q)), dh_forward(np.array(rows), q), rtol=0, atol=1e-9
        )


def test_robot_figures_round_trip_through_rig_json() -> None:
    rows = [(10.0, -90.0, 50.0, 300.0), (-5.0, 0.0, 250.0, 0.0), (0.0, 90.0, 0.0, 20.0)]
    plain = stripecal.Robot(rows, name="three")
    assert plain.repeatability_mm is None and plain.encoder_sigma_deg is None
    robot = stripecal.Robot(rows, name="three", repeatability_mm=0.03, encoder_sigma_deg=0.004)
    assert robot.repeatability_mm == 0.03 and robot.encoder_sigma_deg == 0.004
    assert robot != plain
    rig = stripecal.Rig((640, 480), stripecal.Board.hp3_paper(), robot=robot)
    back = stripecal.Rig.from_json(rig.to_json())
    assert back.robot == robot
    assert '"repeatability_mm": 0.03' in rig.to_json()
    with pytest.raises(stripecal.InvalidInputError, match="repeatability_mm"):
        stripecal.Robot(rows, repeatability_mm=-1.0)


def test_inverse_recovers_a_nearby_pose() -> None:
    robot = stripecal.Robot.hp3()
    q_true = np.array([4.0, 6.0, -5.0, 12.0, -80.0, -20.0])
    target = robot.forward(q_true)
    q = robot.inverse(target, HOME)
    assert q.shape == (6,)
    np.testing.assert_allclose(robot.forward(q), target, atol=1e-8)


def test_jacobian_matches_finite_differences() -> None:
    robot = stripecal.Robot.hp3()
    q = np.array([5.0, -10.0, 12.0, 20.0, -80.0, 30.0])
    jac = robot.jacobian(q)
    assert jac.shape == (6, 6)
    h = 1e-6  # radians
    for i in range(6):
        a, b = q.copy(), q.copy()
        a[i] += np.degrees(h)
        b[i] -= np.degrees(h)
        dv = (robot.forward(a)[:3, 3] - robot.forward(b)[:3, 3]) / (2 * h)
        np.testing.assert_allclose(jac[:3, i], dv, atol=1e-5 * (1 + np.linalg.norm(dv)))


def test_wrong_joint_count_is_an_error() -> None:
    robot = stripecal.Robot.hp3()
    with pytest.raises(ValueError, match=r"\(6,\)"):
        robot.forward([0.0] * 5)
    with pytest.raises(stripecal.InvalidInputError, match="q4"):
        robot.forward([0.0, 0.0, 0.0, np.nan, 0.0, 0.0])
