"""Helpers for the emulator tests: the driver pointed at an emulator, the twin's true joints, waiting on a condition."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from drivers.config import RobotConfig
from drivers.sim import SimWorld
from drivers.xarm7 import XArm7
from drivers.xarm7.emulator import XArmEmulator
from safety.config import SafetyConfig


def make_arm(emulator: XArmEmulator, safety: SafetyConfig, **robot) -> XArm7:
    return XArm7(RobotConfig(kind="xarm7", ip=emulator.address, **robot), safety)


def world_q(world: SimWorld) -> np.ndarray:
    with world.lock:
        return world.data.qpos[world.arm_qpos].copy()


def world_qd(world: SimWorld) -> np.ndarray:
    with world.lock:
        return world.data.qvel[world.arm_dof].copy()


def wait_for(predicate: Callable[[], bool], timeout_s: float = 3.0, period_s: float = 0.002) -> bool:
    """Poll a condition (the SDK's threads give no event to wait on); True as soon as it holds."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return predicate()


def free_loopback_address() -> str:
    """A 127.0.0.N whose ports 502 and 30003 are free right now (for a profile that starts its own emulator)."""
    from drivers.xarm7.emulator.server import bind_controller_ports

    address, command, report = bind_controller_ports(None)
    command.close()
    report.close()
    return address


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def emulated_overrides() -> dict:
    """The emulated profile on its own loopback address and Zenoh port (tests run beside each other)."""
    return {
        "robot": {"ip": free_loopback_address()},
        "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}},
    }
