"""Device interfaces every backend implements (sim, xarm7, femto_bolt).

A device owns its lifecycle: `connect()` is all-or-nothing (a failure releases what it acquired), `close()` is
idempotent, best-effort and always stops motion first. Both are wired to the context manager.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from types import TracebackType
from typing import Self

import numpy as np

from drivers.types import CameraIntrinsics, GripperState, JointState, RGBDFrame


class Device(ABC):
    @abstractmethod
    def connect(self) -> None: ...

    @abstractmethod
    def close(self) -> None: ...

    @property
    @abstractmethod
    def is_connected(self) -> bool: ...

    def __enter__(self) -> Self:
        self.connect()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class Camera(Device):
    @property
    @abstractmethod
    def intrinsics(self) -> CameraIntrinsics: ...

    @abstractmethod
    def read(self, timeout_s: float = 1.0) -> RGBDFrame:
        """Block until a frame newer than the previous one arrives; CameraTimeoutError after timeout_s."""


class Arm(Device):
    joint_names: tuple[str, ...]

    @abstractmethod
    def read_state(self) -> JointState: ...

    @abstractmethod
    def servo(self, q: np.ndarray) -> None:
        """Send one position set-point [rad] for this control tick (servo mode: executed at once)."""

    @abstractmethod
    def stop(self) -> None:
        """Stop immediately and hold position; safe to call at any time, also from another thread."""

    @abstractmethod
    def clear_fault(self) -> None:
        """Clear controller errors and re-enable servo mode."""


class Gripper(Device):
    @abstractmethod
    def read_state(self) -> GripperState: ...

    @abstractmethod
    def command(self, width_m: float) -> None:
        """Move the fingers to a gap of width_m [m]; grasping stops at contact with the object."""

    @abstractmethod
    def stop(self) -> None: ...
