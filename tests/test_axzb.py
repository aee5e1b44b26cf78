"""stripecal.solve_axzb against cv2.calibrateRobotWorldHandEye (method LI) under OpenCV's
own robot-world / hand-eye test noise, plus the API's error cases and fit_laser_plane.

Conventions: ours is A_i X = Z B_i with A_i = T_base_hand, X = T_hand_cam,
Z = T_base_board, B_i = T_board_cam. OpenCV's calibrateRobotWorldHandEye solves
cTw * wTb = cTg * gTb, i.e. it takes world2cam = T_cam_board (= B_i^-1) and
base2gripper = T_hand_base (= A_i^-1) and returns base2world = Z^-1 and
gripper2cam = X^-1.

The data follow OpenCV's test generator (modules/calib3d/test/test_calibration_hand_eye.cpp,
eye-in-hand): unit-scale scene, rotation vectors with noise sigma 0.002 rad on the board
pose in the camera and 0.001 rad on the robot pose, translations sigma 0.005 and 0.001;
10 poses, 100 trials.
"""

from __future__ import annotations

from typing import Callable, Dict, List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import stripecal

cv2 = pytest.importorskip("cv2")

F64 = npt.NDArray[np.float64]


def rodrigues(r: F64) -> F64:
    m, _ = cv2.Rodrigues(np.asarray(r, dtype=np.float64).reshape(3, 1))
    return np.asarray(m, dtype=np.float64)


def rvec(m: F64) -> F64:
    v, _ = cv2.Rodrigues(np.asarray(m, dtype=np.float64))
    return np.asarray(v, dtype=np.float64).ravel()


def make(r: F64, t: F64) -> F64:
    out = np.eye(4)
    out[:3, :3] = r
    out[:3, 3] = np.ravel(t)
    return out


def inv(t: F64) -> F64:
    r = t[:3, :3]
    return make(r.T, -r.T @ t[:3, 3])


def gen_pose(
    rng: np.random.Generator, th: Tuple[float, float], tr: Tuple[float, float]
) -> F64:
    """OpenCV's generatePose: axis uniform in [-1, 1]^3 (not normalised), angle and
    translation components uniform with random signs."""
    axis = rng.uniform(-1.0, 1.0, 3)
    theta = np.deg2rad(rng.uniform(*th)) * np.copysign(1.0, rng.uniform(-1.0, 1.0))
    t = rng.uniform(tr[0], tr[1], 3) * np.copysign(1.0, rng.uniform(-1.0, 1.0, 3))
    return make(rodrigues(theta * axis), t)


def simulate(
    rng: np.random.Generator, n: int, noise: bool
) -> Tuple[F64, F64, List[F64], List[F64]]:
    """Returns (X, Z, A list (T_base_hand, measured), T_cam_board list (measured))."""
    x = gen_pose(rng, (10.0, 50.0), (0.05, 0.5))  # cam2gripper = T_hand_cam
    z = gen_pose(rng, (5.0, 85.0), (0.5, 3.5))  # target2base = T_base_board
    a_list, cb_list = [], []
    for _ in range(n):
        a = gen_pose(rng, (5.0, 45.0), (0.5, 1.5))  # gripper2base = T_base_hand
        cb = inv(x) @ inv(a) @ z  # target2cam = T_cam_board
        if noise:
            cb = make(
                rodrigues(rvec(cb[:3, :3]) + rng.normal(0.0, 0.002, 3)),
                cb[:3, 3] + rng.normal(0.0, 0.005, 3),
            )
            a = make(
                rodrigues(rvec(a[:3, :3]) + rng.normal(0.0, 0.001, 3)),
                a[:3, 3] + rng.normal(0.0, 0.001, 3),
            )
        a_list.append(a)
        cb_list.append(cb)
    return x, z, a_list, cb_list


Solver = Callable[[List[F64], List[F64]], Tuple[F64, F64]]


def ours(refine: bool) -> Solver:
    def solve(a_list: List[F64], cb_list: List[F64]) -> Tuple[F64, F64]:
        b = np.array([inv(cb) for cb in cb_list])
        x, z = stripecal.solve_axzb(np.array(a_list), b, refine=refine)
        return x, z

    return solve


def opencv(method: int) -> Solver:
    def solve(a_list: List[F64], cb_list: List[F64]) -> Tuple[F64, F64]:
        r_w2c = [cb[:3, :3] for cb in cb_list]
        t_w2c = [cb[:3, 3].reshape(3, 1) for cb in cb_list]
        b2g = [inv(a) for a in a_list]
        r_b2g = [t[:3, :3] for t in b2g]
        t_b2g = [t[:3, 3].reshape(3, 1) for t in b2g]
        r_b2w, t_b2w, r_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
            r_w2c, t_w2c, r_b2g, t_b2g, method=method
        )
        return inv(make(r_g2c, t_g2c)), inv(make(r_b2w, t_b2w))

    return solve


def errors(est: F64, truth: F64) -> Tuple[float, float]:
    r = est[:3, :3].T @ truth[:3, :3]
    ang = float(np.degrees(np.linalg.norm(rvec(r))))
    return ang, float(np.linalg.norm(est[:3, 3] - truth[:3, 3]))


SOLVERS: Dict[str, Solver] = {
    "stripecal": ours(True),
    "stripecal (linear only)": ours(False),
    "OpenCV LI": opencv(cv2.CALIB_ROBOT_WORLD_HAND_EYE_LI),
    "OpenCV SHAH": opencv(cv2.CALIB_ROBOT_WORLD_HAND_EYE_SHAH),
}


def test_noise_free_both_recover_the_truth() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        x, z, a_list, cb_list = simulate(rng, 10, noise=False)
        for name, solve in SOLVERS.items():
            xe, ze = solve(a_list, cb_list)
            for est, truth in ((xe, x), (ze, z)):
                r, t = errors(est, truth)
                assert r < 1e-6 and t < 1e-6, (name, r, t)


def test_median_errors_no_worse_than_opencv_li() -> None:
    rng = np.random.default_rng(2024)
    errs: Dict[str, List[List[float]]] = {k: [] for k in SOLVERS}
    for _ in range(100):
        x, z, a_list, cb_list = simulate(rng, 10, noise=True)
        for name, solve in SOLVERS.items():
            xe, ze = solve(a_list, cb_list)
            errs[name].append([*errors(xe, x), *errors(ze, z)])
    med = {k: np.median(np.array(v), axis=0) for k, v in errs.items()}
    print()
    print(
        f"{'median over 100 trials':<26}{'X rot deg':>11}{'X trans':>11}"
        f"{'Z rot deg':>11}{'Z trans':>11}"
    )
    for k, m in med.items():
        print(f"{k:<26}" + "".join(f"{v:>11.5f}" for v in m))
    ours_m, li = med["stripecal"], med["OpenCV LI"]
    assert np.all(ours_m <= li), (ours_m, li)


def test_degenerate_and_bad_input() -> None:
    rng = np.random.default_rng(5)
    x, z, _, _ = simulate(rng, 3, noise=False)
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    a = np.array([make(rodrigues(axis * 0.3 * k), [k, 0.5, -0.2 * k]) for k in range(6)])
    b = np.array([inv(z) @ ai @ x for ai in a])
    with pytest.raises(stripecal.DegenerateError, match="axes span only"):
        stripecal.solve_axzb(a, b)
    with pytest.raises(stripecal.DegenerateError, match="got 2"):
        stripecal.solve_axzb(a[:2], b[:2])
    with pytest.raises(stripecal.InvalidInputError, match="as many"):
        stripecal.solve_axzb(a[:4], b[:3])
    with pytest.raises(stripecal.InvalidInputError, match=r"shape \(N, 4, 4\)"):
        stripecal.solve_axzb(a[:, :3], b)
    bad = b.copy()
    bad[1, 0, 0] = np.nan
    with pytest.raises(stripecal.InvalidInputError, match=r"B\[1\]"):
        stripecal.solve_axzb(a, bad)


def test_full_result_and_refinement_flag() -> None:
    rng = np.random.default_rng(9)
    x, z, a_list, cb_list = simulate(rng, 10, noise=True)
    b = np.array([inv(cb) for cb in cb_list])
    full = stripecal.solve_axzb_full(np.array(a_list), b)
    assert full["X"].shape == (4, 4) and full["Z"].shape == (4, 4)
    assert full["refined"] is True
    assert full["axis_spread_deg"] > 10.0 and full["max_rotation_deg"] > 10.0
    assert 0.0 < full["rotation_residual_rad"] < 0.02
    assert full["warnings"] == []


def test_fit_laser_plane_exact_and_degenerate() -> None:
    cam = stripecal.Camera(768, 576, 1270.0, 1320.0, 384.0, 288.0, "radial1", [0.05, 0, 0, 0, 0])
    n = np.array([0.629, -0.0492, 0.7759])
    n /= np.linalg.norm(n)
    d = 79.87
    poses, stripes = [], []
    for k, (rx, ry, tz) in enumerate([(0.3, 0.1, 100.0), (-0.2, 0.4, 110.0), (0.1, -0.5, 95.0)]):
        cb = make(rodrigues(np.array([np.pi + rx, ry, 0.2 * k])), [-20.0, -15.0, tz])
        # Line of the laser plane and the board plane, in the camera frame.
        nb = cb[:3, :3] @ np.array([0.0, 0.0, 1.0])
        db = nb @ cb[:3, 3]
        direction = np.cross(n, nb)
        a_mat = np.array([n, nb, direction])
        p0 = np.linalg.solve(a_mat, [d, db, 0.0])
        pts = np.array([p0 + s * direction / np.linalg.norm(direction) for s in np.linspace(-15, 15, 40)])
        poses.append(cb)
        stripes.append(cam.project(pts))
    fit = stripecal.fit_laser_plane(np.array(poses), stripes, cam)
    assert np.abs(fit["normal"] - n).max() < 1e-9
    assert abs(fit["d_mm"] - d) < 1e-9
    assert fit["n_points"] == 120 and len(fit["per_view_rms_mm"]) == 3
    with pytest.raises(stripecal.DegenerateError, match="at least 2 views"):
        stripecal.fit_laser_plane(np.array(poses), [stripes[0], np.zeros(0), np.zeros(0)], cam)
    with pytest.raises(stripecal.InvalidInputError, match="3 entries"):
        stripecal.fit_laser_plane(np.array(poses[:2]), stripes, cam)
