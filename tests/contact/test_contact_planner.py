"""Contact planner: pushes, goal poses carried by the motion, and readable rejection reasons."""

from __future__ import annotations

import numpy as np
import pytest
from contact_helpers import clouds, move

from pipeline.contact.planner import plan_contacts
from safety.robot_model import RobotModel


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


def _box_cloud(centre, size, n=3000, seed=0):
    """Points on the visible faces (top and the four sides) of a box resting on the table."""
    rng = np.random.default_rng(seed)
    p = rng.uniform(-0.5, 0.5, (n, 3)) * size
    face = rng.integers(0, 5, n)
    p[face == 0, 2] = size[2] / 2
    p[face == 1, 0], p[face == 2, 0] = size[0] / 2, -size[0] / 2
    p[face == 3, 1], p[face == 4, 1] = size[1] / 2, -size[1] / 2
    return p + np.array([centre[0], centre[1], size[2] / 2])


def _translation(x, y, z=0.0):
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def test_goal_pose_is_the_contact_carried_by_the_motion(robot):
    obj = _box_cloud((0.45, -0.1), np.array([0.05, 0.05, 0.05]))
    motion = _translation(0.05, 0.15, 0.0) @ np.diag([-1.0, -1.0, 1.0, 1.0])  # half turn about base z ...
    motion[:3, 3] += np.array([0.45, -0.1, 0.0]) - motion[:3, :3] @ np.array([0.45, -0.1, 0.0])  # ... about the box
    result = plan_contacts(obj, np.zeros((0, 3)), motion, robot)
    assert result.ok, result.reason
    for plan in result.plans:
        np.testing.assert_allclose(plan.T_goal, motion @ plan.T_contact)
        assert 0.045 < plan.object_width_m < robot.spec.gripper.max_width_m
        np.testing.assert_allclose(robot.tcp_pose(plan.q_contact), plan.T_contact, atol=1e-4)
        np.testing.assert_allclose(robot.tcp_pose(plan.q_goal), plan.T_goal, atol=1e-4)
    assert [p.score for p in result.plans] == sorted((p.score for p in result.plans), reverse=True)
    assert result.best.object_width_m == pytest.approx(0.05, abs=0.004)  # across two faces, not a diagonal


def test_too_wide_object_is_refused_with_the_reason(robot):
    obj = _box_cloud((0.45, 0.0), np.array([0.16, 0.16, 0.05]))
    result = plan_contacts(obj, np.zeros((0, 3)), _translation(0, 0, 0.1), robot)
    assert not result.ok
    assert "too wide for the gripper" in result.reason


def test_unreachable_object_is_refused_with_the_reason(robot):
    obj = _box_cloud((1.3, 0.0), np.array([0.05, 0.05, 0.05]))
    result = plan_contacts(obj, np.zeros((0, 3)), _translation(0, 0, 0.1), robot)
    assert not result.ok
    assert "out of reach" in result.reason


def test_clutter_next_to_the_object_rules_out_colliding_grasps(robot):
    obj = _box_cloud((0.45, 0.0), np.array([0.05, 0.05, 0.05]))
    free = plan_contacts(obj, np.zeros((0, 3)), _translation(0, 0, 0.1), robot)
    wall = _box_cloud((0.45, 0.06), np.array([0.2, 0.03, 0.12]), seed=1)  # a tall wall just beside it
    walled = plan_contacts(obj, wall, _translation(0, 0, 0.1), robot)
    assert free.ok and walled.rejected.get("gripper hits the scene at contact", 0) > 0
    for plan in walled.plans:  # whatever remains closes across the wall's direction, not into it
        assert abs(plan.T_contact[1, 1]) < 0.5


def test_push_moves_the_object_along_the_motion(robot, sim_profile_with):
    from drivers.sim import SimArm, SimCamera, SimGripper, SimWorld

    profile = sim_profile_with({"sim": {"scene": "pick_place"}})
    world = SimWorld(profile.sim, profile.camera)
    camera, arm, gripper = SimCamera(world), SimArm(world), SimGripper(world)
    for device in (camera, arm, gripper):
        device.connect()
    try:
        obj, scene, eye = clouds(world, camera, robot, "red_box")
        result = plan_contacts(
            obj, scene, _translation(0.0, 0.10), robot, mode="push", q_seed=arm.read_state().q, viewpoint=eye
        )
        assert result.ok, result.reason
        plan = result.best
        assert plan.mode == "push" and plan.width_m == pytest.approx(robot.spec.gripper.min_width_m)
        assert plan.T_contact[1, 3] < obj[:, 1].min()  # behind the box, opposite the push direction
        y0 = world.object_pose("red_box")[1, 3]
        gripper.command(plan.width_m)
        move(world, arm, plan.q_pre, 2.0)
        move(world, arm, plan.q_contact, 1.5)
        move(world, arm, plan.q_goal, 2.0)
        world.step(0.5)
        assert world.object_pose("red_box")[1, 3] - y0 > 0.06
    finally:
        for device in (camera, arm, gripper):
            device.close()
