"""IK round trips on random reachable poses, limits, preferred posture, acceptance check and honest failure."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from safety.ik import IKSettings


def _errors(robot, q, T_target) -> tuple[float, float]:
    T = robot.tcp_pose(q)
    rot = np.linalg.norm(pin.log3(T[:3, :3].T @ T_target[:3, :3]))
    return float(np.linalg.norm(T[:3, 3] - T_target[:3, 3])), float(rot)


def test_round_trip_500_random_reachable_poses(robot):
    rng = np.random.default_rng(11)
    margin = IKSettings().margin_rad
    successes, worst = 0, (0.0, 0.0)
    n = 500
    for _ in range(n):
        T_target = robot.tcp_pose(rng.uniform(robot.lower + margin, robot.upper - margin))
        res = robot.ik(T_target)
        if res.success:
            pos, rot = _errors(robot, res.q, T_target)
            assert pos < 1e-4 and rot < 0.01, (pos, rot)
            assert robot.within_limits(res.q, margin - 1e-9)
            worst = (max(worst[0], pos), max(worst[1], rot))
            successes += 1
    assert successes >= 0.99 * n, f"{successes}/{n} solved"


def test_seed_near_solution_converges_to_nearby_configuration(robot):
    q_true = robot.home_q + np.array([0.2, 0.1, -0.1, 0.15, 0.1, -0.1, 0.3])
    res = robot.ik(robot.tcp_pose(q_true), q_seed=q_true + 0.02)
    assert res.success and res.attempts == 1
    assert np.max(np.abs(res.q - q_true)) < 0.1


def test_unreachable_pose_reports_residual(robot):
    T = np.eye(4)
    T[:3, 3] = [2.0, 0.0, 0.5]  # 2 m away: beyond the ~0.9 m reach
    res = robot.ik(T, settings=IKSettings(restarts=3))
    assert not res.success
    assert res.position_error_m > 0.5
    assert "best residual" in res.reason and "mm" in res.reason
    assert res.attempts == 4  # the preferred posture (home) + 3 random restarts


def test_accept_callback_rejects_solutions(robot):
    T = robot.tcp_pose(robot.home_q)
    res = robot.ik(T, accept=lambda q: False, settings=IKSettings(restarts=2))
    assert not res.success and "rejected by the acceptance check" in res.reason
    wrist_up = robot.ik(T, accept=lambda q: q[5] > 0.5)
    assert wrist_up.success and wrist_up.q[5] > 0.5
