"""A hinge push planned on the sim camera's view of an open lid really closes it."""

from __future__ import annotations

import math

import numpy as np
from contact_helpers import body_motion, clouds, hinge_angle, move

from pipeline.contact.planner import plan_contacts
from safety.robot_model import RobotModel


def test_arc_push_closes_the_lid(sim_profile_with):
    from drivers.sim import SimArm, SimCamera, SimGripper, SimWorld

    robot = RobotModel()
    profile = sim_profile_with({"sim": {"scene": "close_lid"}})
    world = SimWorld(profile.sim, profile.camera)
    camera, arm, gripper = SimCamera(world), SimArm(world), SimGripper(world)
    for device in (camera, arm, gripper):
        device.connect()
    try:
        world.step(1.5)  # the lid, 10 deg past vertical, is held open by its hinge's friction
        opened = hinge_angle(world, "box_hinge")
        assert math.degrees(opened) > 95.0
        lid, scene, eye = clouds(world, camera, robot, "box", body="box_lid")
        closing = body_motion(world, "box_lid", "box_hinge", 0.0)
        result = plan_contacts(lid, scene, closing, robot, mode="hinge", q_seed=arm.read_state().q, viewpoint=eye)
        assert result.ok, result.reason
        plan = result.best
        assert plan.mode == "hinge" and len(plan.q_via) == len(plan.via) == math.ceil(math.degrees(opened) / 10) - 1
        assert plan.T_contact[0, 3] < lid[:, 0].min()  # on the robot's side of the lid: it pushes away
        gripper.command(plan.width_m)
        move(world, arm, plan.q_pre, 1.5)
        move(world, arm, plan.q_contact, 1.0)
        assert math.degrees(hinge_angle(world, "box_hinge")) > 95.0  # the approach has not touched the lid
        for q in (*plan.q_via, plan.q_goal):
            move(world, arm, q, 0.3)
        world.step(0.5)
        closed = math.degrees(hinge_angle(world, "box_hinge"))
        assert closed < 15.0, f"lid still open {closed:.0f} deg"
        assert np.linalg.norm(world.tcp_pose()[:3, 3] - plan.T_goal[:3, 3]) < 0.01  # the fingers rest above it
    finally:
        for device in (camera, arm, gripper):
            device.close()
