"""Fixtures for the emulator tests: a live twin (physics on the wall clock, like hardware), the controller emulator
on a free loopback address, and the real XArm7 driver connected to it through xarm-python-sdk."""

from __future__ import annotations

import pytest
from emulator_helpers import make_arm

from drivers.sim import SimWorld
from drivers.xarm7 import XArmGripper
from drivers.xarm7.emulator import XArmEmulator
from motion.limits import MotionLimits
from motion.timing import TrajectoryTimer
from safety.config import SafetyConfig
from safety.robot_model import RobotModel


@pytest.fixture(scope="session")
def robot_model() -> RobotModel:
    return RobotModel()


@pytest.fixture
def world(sim_profile_with):
    profile = sim_profile_with({"sim": {"realtime": True}})
    w = SimWorld(profile.sim, profile.camera)
    yield w
    w.stop()


@pytest.fixture
def emulator(world):
    with XArmEmulator(world) as e:
        yield e


@pytest.fixture
def safety() -> SafetyConfig:
    return SafetyConfig()


@pytest.fixture
def arm(emulator, safety):
    a = make_arm(emulator, safety)
    a.connect()
    yield a
    a.close()


@pytest.fixture
def gripper(arm):
    g = XArmGripper(arm)
    g.connect()
    return g


@pytest.fixture
def timer(robot_model, safety) -> TrajectoryTimer:
    limits = MotionLimits.from_config(safety, robot_model.spec)
    return TrajectoryTimer(limits, 0.01, robot_model.joint_names, robot_model.tcp_positions, safety.max_tcp_speed_m_s)
