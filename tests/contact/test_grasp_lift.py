"""Contact sampling on the camera's cloud yields a grasp that really lifts each scene object in the sim."""

from __future__ import annotations

import numpy as np
import pytest
from contact_helpers import clouds, execute_grasp

from pipeline.contact.planner import plan_contacts
from safety.robot_model import RobotModel

LIFT_M = 0.10
CASES = [
    ("pick_place", "red_box"),
    ("pick_place", "blue_box"),
    ("pick_place", "green_cylinder"),
    ("pick_place", "yellow_cylinder"),
    ("tomato_pan", "tomato"),
    ("bottle_standup", "bottle"),
    ("block_scale", "yellow_block"),
]


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


@pytest.mark.parametrize(("scene", "name"), CASES)
def test_planned_grasp_lifts_the_object(scene, name, robot, sim_profile_with):
    from drivers.sim import SimArm, SimCamera, SimGripper, SimWorld

    profile = sim_profile_with({"sim": {"scene": scene}})
    world = SimWorld(profile.sim, profile.camera)
    camera, arm, gripper = SimCamera(world), SimArm(world), SimGripper(world)
    for device in (camera, arm, gripper):
        device.connect()
    try:
        obj, scene_pts, eye = clouds(world, camera, robot, name)
        lift = np.eye(4)
        lift[2, 3] = LIFT_M
        result = plan_contacts(obj, scene_pts, lift, robot, q_seed=arm.read_state().q, viewpoint=eye)
        assert result.ok, result.reason
        plan = result.best
        assert plan.mode == "grasp" and 0 <= plan.width_m < plan.object_width_m <= robot.spec.gripper.max_width_m
        z0 = world.object_pose(name)[2, 3]
        execute_grasp(world, arm, gripper, plan)
        rise = world.object_pose(name)[2, 3] - z0
        assert rise > 0.7 * LIFT_M, f"{name} rose {rise * 1000:.0f} mm"
        assert gripper.read_state().width_m > 0.005  # the object is between the fingers
    finally:
        for device in (camera, arm, gripper):
            device.close()
