"""Runtime test fixtures: Zenoh bound to 127.0.0.1 on a free port, never the default one."""

from __future__ import annotations

import pytest
from runtime_helpers import free_port

from runtime.config import RuntimeConfig, ZenohConfig


@pytest.fixture
def zenoh_cfg() -> ZenohConfig:
    return ZenohConfig(endpoint=f"tcp/127.0.0.1:{free_port()}")


@pytest.fixture
def runtime_cfg(zenoh_cfg) -> RuntimeConfig:
    return RuntimeConfig(robot_id="test_robot", zenoh=zenoh_cfg)
