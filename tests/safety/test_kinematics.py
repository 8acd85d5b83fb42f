"""Forward kinematics against the facts sheet (robots/xarm7_facts.yaml): the computed zero-configuration check
and UFACTORY's published DH tables; Jacobian against finite differences; dexterity measures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

# facts: dh_modified_mm_rad / dh_standard_mm_rad rows [theta, d_mm, alpha_rad, a_mm, offset_rad], joint1..7
DH_MODIFIED = [
    [0, 267, 0, 0, 0],
    [0, 0, -1.570796327, 0, 0],
    [0, 293, 1.570796327, 0, 0],
    [0, 0, 1.570796327, 52.5, 0],
    [0, 342.5, 1.570796327, 77.5, 0],
    [0, 0, 1.570796327, 0, 0],
    [0, 97, -1.570796327, 76, 0],
]
DH_STANDARD = [
    [0, 267, -1.570796327, 0, 0],
    [0, 0, 1.570796327, 0, 0],
    [0, 293, 1.570796327, 52.5, 0],
    [0, 0, 1.570796327, 77.5, 0],
    [0, 342.5, 1.570796327, 0, 0],
    [0, 0, -1.570796327, 76, 0],
    [0, 97, 0, 0, 0],
]


def _rot(axis: str, angle: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler(axis, angle).as_matrix()
    return T


def _trans(x=0.0, z=0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, 0.0, z]
    return T


def fk_modified_dh(q: np.ndarray) -> np.ndarray:
    """Craig: T_i = RotX(alpha_{i-1}) TransX(a_{i-1}) RotZ(theta_i) TransZ(d_i)."""
    T = np.eye(4)
    for qi, (theta, d, alpha, a, offset) in zip(q, DH_MODIFIED, strict=True):
        T = T @ _rot("x", alpha) @ _trans(x=a / 1000) @ _rot("z", theta + qi + offset) @ _trans(z=d / 1000)
    return T


def fk_standard_dh(q: np.ndarray) -> np.ndarray:
    """T_i = RotZ(theta_i) TransZ(d_i) TransX(a_i) RotX(alpha_i)."""
    T = np.eye(4)
    for qi, (theta, d, alpha, a, offset) in zip(q, DH_STANDARD, strict=True):
        T = T @ _rot("z", theta + qi + offset) @ _trans(z=d / 1000) @ _trans(x=a / 1000) @ _rot("x", alpha)
    return T


def test_zero_configuration_matches_facts_check(robot):
    # facts: fk_check_zero_config_computed
    poses = robot.fk(np.zeros(7))
    np.testing.assert_allclose(poses["link7"][:3, 3], [0.206, 0.0, 0.1205], atol=2e-5)
    np.testing.assert_allclose(Rotation.from_matrix(poses["link7"][:3, :3]).as_euler("xyz"), [-np.pi, 0, 0], atol=1e-4)
    np.testing.assert_allclose(poses["link_tcp"][:3, 3], [0.206, 0.0, -0.0515], atol=2e-5)
    np.testing.assert_allclose(robot.tcp_pose(np.zeros(7)), poses["link_tcp"], atol=1e-12)


def test_fk_covers_every_link_and_the_fingers(robot):
    poses = robot.fk(robot.home_q, gripper_width_m=0.04)
    assert set(poses) >= {"link_base", *(f"link{i}" for i in range(1, 8)), "link_tcp", "left_finger", "right_finger"}
    gap = poses["left_finger"][:3, 3] - poses["right_finger"][:3, 3]
    assert np.linalg.norm(gap) == pytest.approx(0.04, abs=1e-9)


def test_fk_agrees_with_published_dh_tables(robot):
    rng = np.random.default_rng(3)
    for _ in range(200):
        q = rng.uniform(robot.lower, robot.upper)
        T = robot.frame_pose(q, "link7")
        np.testing.assert_allclose(fk_modified_dh(q), T, atol=5e-5)  # URDF writes pi/2 as 1.5708
        np.testing.assert_allclose(fk_standard_dh(q)[:3, 3], T[:3, 3], atol=5e-5)


def test_jacobian_matches_finite_differences(robot):
    rng = np.random.default_rng(4)
    q = rng.uniform(robot.lower + 0.1, robot.upper - 0.1)
    J = robot.jacobian(q)
    eps = 1e-6
    for i in range(7):
        dq = np.zeros(7)
        dq[i] = eps
        Tp, Tm = robot.tcp_pose(q + dq), robot.tcp_pose(q - dq)
        np.testing.assert_allclose((Tp[:3, 3] - Tm[:3, 3]) / (2 * eps), J[:3, i], atol=1e-6)
        w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * eps)
        np.testing.assert_allclose(w, J[3:, i], atol=1e-6)


def test_manipulability_and_condition_number_flag_singularity(robot):
    q_singular = np.zeros(7)
    q_singular[3] = np.pi  # elbow straight: arm fully stretched, a singularity
    assert robot.manipulability(q_singular) < 1e-6
    assert robot.condition_number(q_singular) > 1e6
    assert robot.manipulability(robot.home_q) > 1e-3
    assert 1 < robot.condition_number(robot.home_q) < 100


def test_tcp_positions_batch_matches_single(robot):
    rng = np.random.default_rng(5)
    Q = rng.uniform(robot.lower, robot.upper, size=(10, 7))
    batch = robot.tcp_positions(Q)
    for q, p in zip(Q, batch, strict=True):
        np.testing.assert_allclose(robot.tcp_pose(q)[:3, 3], p, atol=1e-12)


def test_wrong_joint_count_is_refused(robot):
    with pytest.raises(ValueError, match="expected 7 joint angles"):
        robot.tcp_pose(np.zeros(6))
    with pytest.raises(KeyError, match="unknown frame"):
        robot.frame_pose(np.zeros(7), "link9")


def test_per_call_gripper_width_does_not_change_the_default(robot):
    default = robot.gripper_width_m
    robot.fk(robot.home_q, gripper_width_m=0.01)
    assert robot.gripper_width_m == default
    poses = robot.fk(robot.home_q)
    gap = np.linalg.norm(poses["left_finger"][:3, 3] - poses["right_finger"][:3, 3])
    assert gap == pytest.approx(default)
