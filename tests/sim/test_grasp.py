"""A box is really grasped and lifted: closing the gripper around it holds it by friction."""

import numpy as np

from drivers.sim import SimArm, SimGripper, SimWorld
from motion.interpolate import minimum_jerk_path
from sim_helpers import ik, top_down_grasp_pose

RATE = 100.0


def move(world, arm, q_target):
    for q in minimum_jerk_path(arm.read_state().q, q_target, RATE, max_velocity=1.0):
        arm.servo(q)
        world.step(1.0 / RATE)
    world.step(0.3)


def test_box_is_grasped_and_lifted(stepped_profile):
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    T_box = world.object_pose("red_block")
    z0 = T_box[2, 3]
    with SimArm(world, RATE) as arm, SimGripper(world) as gripper:
        q = arm.read_state().q
        for height in (0.15, 0.03):  # above, then fingers around the top of the 5 cm block
            q = ik(world, top_down_grasp_pose(T_box, height), q)
            move(world, arm, q)
        gripper.command(0.0)
        world.step(1.0)
        width = gripper.read_state().width_m
        assert 0.045 < width < 0.052  # stopped by the 5 cm block, not closed
        q = ik(world, top_down_grasp_pose(T_box, 0.20), q)
        move(world, arm, q)
        world.step(0.5)
    lifted = world.object_pose("red_block")
    assert lifted[2, 3] - z0 > 0.15
    tcp = world.tcp_pose()
    offset = np.linalg.inv(tcp) @ lifted
    assert np.linalg.norm(offset[:2, 3]) < 0.01  # still centred between the fingers


def test_block_stays_put_when_the_gripper_closes_beside_it(stepped_profile):
    """Control: without the object between the fingers nothing is lifted."""
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    T_box = world.object_pose("red_block")
    z0 = T_box[2, 3]
    beside = T_box.copy()
    beside[1, 3] += 0.12  # 12 cm to the side of the block
    with SimArm(world, RATE) as arm, SimGripper(world) as gripper:
        q = ik(world, top_down_grasp_pose(beside, 0.10), arm.read_state().q)
        move(world, arm, q)
        gripper.command(0.0)
        world.step(1.0)
        assert gripper.read_state().width_m < 0.01
        move(world, arm, ik(world, top_down_grasp_pose(beside, 0.25), q))
    assert abs(world.object_pose("red_block")[2, 3] - z0) < 0.005
