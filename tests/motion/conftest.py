"""Fixtures for motion tests: the safety model and collision world, a timer, and a sim arm on a stepped clock."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim.arm import SimArm, SimGripper
from drivers.sim.world import SimWorld
from motion.limits import MotionLimits
from motion.timing import TrajectoryTimer
from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.geometry import Primitive, pose
from safety.robot_model import RobotModel


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel()


@pytest.fixture(scope="session")
def safety() -> SafetyConfig:
    return SafetyConfig()


@pytest.fixture(scope="session")
def limits(robot, safety) -> MotionLimits:
    return MotionLimits.from_config(safety, robot.spec)


@pytest.fixture(scope="session")
def timer(robot, safety, limits) -> TrajectoryTimer:
    return TrajectoryTimer(limits, 0.01, robot.joint_names, robot.tcp_positions, safety.max_tcp_speed_m_s)


@pytest.fixture
def free_world(robot, safety) -> CollisionWorld:
    return CollisionWorld(robot.copy(), safety)


def wall_between(robot: RobotModel, q_a: np.ndarray, q_b: np.ndarray) -> Primitive:
    """A thin wall standing between the TCP positions of q_a and q_b, so the direct move is blocked."""
    pa, pb = robot.tcp_pose(q_a)[:3, 3], robot.tcp_pose(q_b)[:3, 3]
    mid = (pa + pb) / 2
    return Primitive("wall", "world", "box", (0.18, 0.02, 0.30), pose((mid[0], mid[1], 0.15)))


@pytest.fixture
def sim(stepped_profile):
    """A stepped sim world with a connected arm and gripper."""
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    arm, gripper = SimArm(world, stepped_profile.robot.control_rate_hz), SimGripper(world)
    arm.connect()
    gripper.connect()
    yield world, arm, gripper
    arm.close()
    gripper.close()
