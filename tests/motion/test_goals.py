"""IK goals (ranked, collision-free) and straight-line approach/retreat along the gripper axis."""

from __future__ import annotations

import numpy as np
import pytest

from motion.approval import approve
from motion.cartesian import CartesianPathError, cartesian_path
from motion.goals import GoalError, ik_goals, lifted, tool_offset
from motion.planner import Planner
from safety.collision import CollisionWorld
from safety.geometry import Primitive, pose


def top_down(x: float, y: float, z: float, yaw: float = 0.0) -> np.ndarray:
    """TCP pose pointing straight down (gripper axis -z of the base)."""
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = np.array([[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]])
    T[:3, 3] = (x, y, z)
    return T


def test_offsets_move_along_the_gripper_axis():
    T = top_down(0.4, 0.1, 0.05, yaw=0.3)
    np.testing.assert_allclose(tool_offset(T, 0.1)[:3, 3], [0.4, 0.1, 0.15])
    np.testing.assert_allclose(tool_offset(T, 0.1)[:3, :3], T[:3, :3])
    np.testing.assert_allclose(lifted(T, 0.2)[:3, 3], [0.4, 0.1, 0.25])


def test_goals_are_exact_collision_free_and_ranked(robot, safety, limits):
    post = Primitive("post", "world", "box", (0.06, 0.06, 0.25), pose((0.45, 0.22, 0.125)))
    world = CollisionWorld(robot.copy(), safety, obstacles=[post])
    target = top_down(0.45, 0.0, 0.12, yaw=0.4)
    q_now = robot.home_q
    goals = ik_goals(world, limits, target, q_now, max_solutions=4, attempts=12)
    assert goals
    for g in goals:
        T = robot.tcp_pose(g.q)
        assert np.linalg.norm(T[:3, 3] - target[:3, 3]) < 1e-4
        assert np.abs(T[:3, :3] - target[:3, :3]).max() < 1e-3
        assert not world.in_collision(g.q)
        assert np.all(g.q >= limits.lower) and np.all(g.q <= limits.upper)
    assert [g.cost for g in goals] == sorted(g.cost for g in goals)
    assert goals[0].distance_rad < 2.0  # the first is near the current posture, not a far-away flip


def test_unreachable_goal_is_reported(robot, safety, limits, free_world):
    with pytest.raises(GoalError, match="no collision-free"):
        ik_goals(free_world, limits, top_down(1.5, 0.0, 0.3), robot.home_q, attempts=3)


def test_approach_is_a_straight_tcp_line_that_passes_the_gate(robot, safety, limits, timer):
    grasp = top_down(0.42, -0.05, 0.06, yaw=0.2)
    pre = tool_offset(grasp, 0.12)
    world = CollisionWorld(robot.copy(), safety)
    planner = Planner(world, limits)
    q_pre = ik_goals(world, limits, pre, robot.home_q)[0].q
    waypoints = cartesian_path(planner, q_pre, grasp)
    assert 2 <= len(waypoints) < 25  # thinned from the 24 dense steps
    np.testing.assert_allclose(robot.tcp_pose(waypoints[-1])[:3, 3], grasp[:3, 3], atol=1e-4)
    traj = timer.time([waypoints])
    tcp = robot.tcp_positions(traj.positions)
    a, b = pre[:3, 3], grasp[:3, 3]
    s = np.clip((tcp - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
    off_line = np.linalg.norm(tcp - (a + s[:, None] * (b - a)), axis=1)
    assert off_line.max() < 0.0025
    assert approve(traj, world, q_current=q_pre).report.ok


def test_blocked_line_is_refused_with_the_place(robot, safety, limits):
    grasp = top_down(0.42, -0.05, 0.06)
    pre = tool_offset(grasp, 0.12)
    plate = Primitive("plate", "world", "box", (0.2, 0.2, 0.01), pose((0.42, -0.05, 0.12)))
    world = CollisionWorld(robot.copy(), safety)
    q_pre = ik_goals(world, limits, pre, robot.home_q)[0].q
    world.set_obstacles([plate])
    with pytest.raises(CartesianPathError, match=r"collision .*of the way.*plate"):
        cartesian_path(Planner(world, limits), q_pre, grasp)


def test_configuration_jump_is_refused(robot, safety, limits):
    """A joint change above max_jump_rad between two 5 mm steps is refused as a flip, naming the joint."""
    grasp = top_down(0.42, -0.05, 0.06)
    world = CollisionWorld(robot.copy(), safety)
    q_pre = ik_goals(world, limits, tool_offset(grasp, 0.12), robot.home_q)[0].q
    with pytest.raises(CartesianPathError, match=r"joint \d jumps .* \(flip or singularity\)"):
        cartesian_path(Planner(world, limits), q_pre, grasp, max_jump_rad=0.001)
