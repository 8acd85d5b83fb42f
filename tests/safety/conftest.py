"""Session-wide robot model for the safety tests (building it costs milliseconds, not per test)."""

from __future__ import annotations

import pytest

from safety.robot_model import RobotModel


@pytest.fixture(scope="session")
def robot() -> RobotModel:
    return RobotModel()
