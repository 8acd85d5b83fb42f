"""Fixtures the contact tests share: the robot model and the sim profile's safety settings."""

from __future__ import annotations

import pytest

from runtime.config import load_profile
from safety.robot_model import RobotModel


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


@pytest.fixture(scope="module")
def safety():
    return load_profile("configs/sim.yaml").safety
