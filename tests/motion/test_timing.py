"""Ruckig timing: straight lines at rest-to-rest, limits held by the sampled positions, blending, fallbacks."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from motion.limits import MotionLimits
from motion.timing import GripperAction, TimingError, TrajectoryTimer


def _waypoints(robot, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = [robot.home_q]
    for _ in range(n - 1):
        q.append(q[-1] + rng.uniform(-0.4, 0.4, 7))
    return np.array(q)


def _distance_to_polyline(q: np.ndarray, waypoints: np.ndarray) -> np.ndarray:
    """Joint-space distance of each sample to the nearest segment of the polyline."""
    best = np.full(len(q), np.inf)
    for a, b in pairwise(waypoints):
        d = b - a
        s = np.clip((q - a) @ d / max(d @ d, 1e-18), 0, 1)
        best = np.minimum(best, np.linalg.norm(q - (a + s[:, None] * d), axis=1))
    return best


def _within_limits(traj, limits: MotionLimits, tol: float = 1e-9) -> None:
    for order, bound in ((1, limits.velocity), (2, limits.acceleration), (3, limits.jerk)):
        peak = np.max(np.abs(traj.derivative(order)), axis=0)
        assert np.all(peak <= bound * (1 + tol)), f"order {order}: {peak} > {bound}"


def test_rest_to_rest_runs_on_the_straight_lines_within_limits(robot, limits):
    timer = TrajectoryTimer(limits, 0.01, robot.joint_names)
    waypoints = _waypoints(robot, 4, seed=1)
    traj = timer.time([waypoints])
    np.testing.assert_allclose(traj.positions[0], waypoints[0], atol=1e-12)
    np.testing.assert_allclose(traj.positions[-1], waypoints[-1], atol=1e-9)
    assert _distance_to_polyline(traj.positions, waypoints).max() < 1e-9
    _within_limits(traj, limits)
    # the arm rests at each interior waypoint: some sample lies (almost) on it with (almost) zero speed
    speed = np.linalg.norm(traj.derivative(1), axis=1)
    for w in waypoints[1:-1]:
        k = int(np.argmin(np.linalg.norm(traj.positions - w, axis=1)))
        assert np.linalg.norm(traj.positions[k] - w) < 1e-3 and speed[k] < 0.2


def test_point_to_point_is_time_optimal(robot, limits):
    """A single move hits at least one limit: it cannot be made faster by more than one sample period."""
    timer = TrajectoryTimer(limits, 0.004, robot.joint_names)
    q0 = robot.home_q
    traj = timer.time([np.array([q0, q0 + np.array([1.2, 0.4, -0.3, 0.5, 0.2, -0.4, 1.0])])])
    usage = max(np.max(np.abs(traj.derivative(o)) / b) for o, b in ((1, limits.velocity), (2, limits.acceleration)))
    assert usage > 0.97


def test_speed_scale_stretches_time(robot, safety):
    waypoints = _waypoints(robot, 3, seed=2)
    durations = []
    for scale in (1.0, 0.5):
        limits = MotionLimits.from_config(safety, robot.spec, speed_scale=scale)
        durations.append(TrajectoryTimer(limits, 0.002, robot.joint_names).time([waypoints]).duration_s)
    assert durations[1] == pytest.approx(2 * durations[0], abs=0.01)
    with pytest.raises(ValueError, match="speed_scale"):
        MotionLimits.from_config(safety, robot.spec, speed_scale=1.5)


def test_tcp_speed_limit_slows_fast_segments(robot, limits):
    q0 = robot.home_q
    path = np.array([q0, q0 + np.array([1.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0])])
    free = TrajectoryTimer(limits, 0.01, robot.joint_names).time([path])
    capped = TrajectoryTimer(limits, 0.01, robot.joint_names, robot.tcp_positions, 0.3).time([path])
    tcp_speed = lambda tr: np.linalg.norm(np.diff(robot.tcp_positions(tr.positions), axis=0), axis=1) / tr.dt  # noqa: E731
    assert tcp_speed(free).max() > 0.5
    assert tcp_speed(capped).max() <= 0.3
    assert _distance_to_polyline(capped.positions, path).max() < 1e-9


def test_blending_is_faster_and_respects_limits(robot, limits):
    timer = TrajectoryTimer(limits, 0.01, robot.joint_names)
    q0 = robot.home_q
    # a path that keeps every joint's direction: blending must not stop at the waypoints
    waypoints = (
        q0
        + np.outer([0, 0.3, 0.6, 0.9, 1.2], [0.5, 0.3, -0.4, 0.5, 0.3, 0.2, 0.6])
        + np.array([np.zeros(7), [0.05, 0, 0, 0, 0, 0, 0], np.zeros(7), [0, 0.05, 0, 0, 0, 0, 0], np.zeros(7)])
    )
    stop = timer.time([waypoints])
    blended = timer.time([waypoints], blend=True, check=lambda tr: [])
    assert blended.duration_s < 0.85 * stop.duration_s
    _within_limits(blended, limits, tol=1e-6)
    np.testing.assert_allclose(blended.positions[-1], waypoints[-1], atol=1e-9)


def test_rejected_blend_falls_back_to_straight_segments(robot, limits):
    """A check that rejects every bent sample in the last segment: the crossing into it is dropped, the earlier
    crossings stay, and the result is accepted, faster than stopping, and straight where it was rejected."""
    timer = TrajectoryTimer(limits, 0.01, robot.joint_names)
    waypoints = robot.home_q + np.outer([0, 0.4, 0.8, 1.2, 1.6], [0.5, 0.3, -0.4, 0.5, 0.3, 0.2, 0.6])
    waypoints[2] += [0.1, -0.05, 0, 0.05, 0, 0, 0]
    last = waypoints[-2:]
    calls = []

    def check(tr):
        calls.append(tr)
        near_end = np.linalg.norm(tr.positions - last[1], axis=1) < np.linalg.norm(last[1] - last[0])
        bent = _distance_to_polyline(tr.positions, last) > 1e-6
        return list(tr.times[near_end & bent])

    stop = timer.time([waypoints])
    traj = timer.time([waypoints], blend=True, check=check)
    assert len(calls) >= 2 and check(traj) == []
    assert traj.duration_s < 0.95 * stop.duration_s
    near_end = np.linalg.norm(traj.positions - last[1], axis=1) < np.linalg.norm(last[1] - last[0])
    assert _distance_to_polyline(traj.positions[near_end], last).max() < 1e-6


def test_gripper_actions_hold_the_arm(robot, limits, timer):
    q0 = robot.home_q
    q1 = q0 + np.array([0.3, 0.1, 0, 0.1, 0, 0, 0])
    traj = timer.time([np.array([q0, q1]), GripperAction("close", 0.5, 0.01), np.array([q1, q0])])
    (event,) = traj.gripper_events
    assert event.kind == "close" and event.width_m == 0.01 and event.duration_s == 0.5
    hold = (traj.times >= event.time_s) & (traj.times <= event.time_s + event.duration_s)
    assert hold.sum() >= 49
    np.testing.assert_allclose(traj.positions[hold], np.broadcast_to(q1, (hold.sum(), 7)), atol=1e-9)


def test_bad_input_is_named(robot, limits, timer):
    q0 = robot.home_q
    outside = q0.copy()
    outside[1] = 3.0
    with pytest.raises(TimingError, match="joint 2"):
        timer.time([np.array([q0, outside])])
    with pytest.raises(TimingError, match="do not join"):
        timer.time([np.array([q0, q0 + 0.1]), np.array([q0, q0 + 0.2])])
    with pytest.raises(TimingError, match="check"):
        timer.time([np.array([q0, q0 + 0.1, q0 + 0.2])], blend=True)
    with pytest.raises(TimingError, match="first step"):
        timer.time([GripperAction("open", 0.2, 0.08), np.array([q0, q0 + 0.1])])
