"""Helpers for the runtime tests: free loopback ports, polling, a recording fake arm."""

from __future__ import annotations

import socket
import threading
import time

import numpy as np

from drivers.errors import ArmStoppedError
from drivers.interfaces import Arm
from drivers.types import JointState


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def sim_run_profile(sim_config_path, scene: str, seed: int, robot_id: str = "e2e"):
    """The sim profile for one whole run of a scene and seed, on its own loopback Zenoh port."""
    from runtime.config import load_profile

    return load_profile(
        sim_config_path,
        {
            "sim": {"seed": seed, "scene": scene},
            "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": robot_id},
        },
    )


def wait_for(predicate, timeout_s: float = 3.0, period_s: float = 0.005) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(period_s)
    return predicate()


class RecordingArm(Arm):
    """A fake arm that records when stop() was called and refuses set-points after it, like the driver."""

    joint_names = tuple(f"joint{i}" for i in range(1, 8))

    def __init__(self) -> None:
        self.q = np.zeros(7)
        self.stopped = threading.Event()
        self.stop_times: list[float] = []
        self.fault_code = 0
        self.broken = False

    @property
    def is_connected(self) -> bool:
        return True

    def connect(self) -> None: ...

    def close(self) -> None:
        self.stop()

    def read_state(self) -> JointState:
        if self.broken:
            from drivers.errors import DriverError

            raise DriverError("link lost")
        return JointState(self.joint_names, self.q.copy(), np.zeros(7), time.monotonic(), self.fault_code)

    def servo(self, q) -> None:
        if self.stopped.is_set():
            raise ArmStoppedError("stopped")
        self.q = np.asarray(q, float)

    def stop(self) -> None:
        self.stop_times.append(time.perf_counter())
        self.stopped.set()

    def clear_fault(self) -> None:
        self.stopped.clear()
        self.fault_code = 0
