"""The xArm Gripper through the arm's SDK connection: finger gap in metres outside, SDK 0..850 inside."""

from __future__ import annotations

import math
import time

import numpy as np

from drivers.errors import NotConnectedError
from drivers.interfaces import Gripper
from drivers.types import GripperState
from drivers.xarm7.arm import XArm7
from drivers.xarm7.codes import check

POSITION_MODE = 0
WIDTH_TOLERANCE_M = 0.002  # a request this far outside the stroke is an error, closer ones are clamped


class XArmGripper(Gripper):
    """Shares the XArm7's connection (connect the arm first, as open_devices does)."""

    def __init__(self, arm: XArm7, speed: int | None = None) -> None:
        self.arm = arm
        self.spec = arm.spec.gripper
        self.speed = speed or arm.config.gripper_speed
        self._connected = False
        self._target_sdk = float(self.spec.sdk_open)

    @property
    def is_connected(self) -> bool:
        return self._connected and self.arm.is_connected

    def _api(self, what: str):
        if not self.is_connected:
            raise NotConnectedError(f"XArmGripper.{what} before connect() or after the arm closed")
        return self.arm.api

    def connect(self) -> None:
        if self._connected:
            return
        api = self.arm.api
        if api is None:
            raise NotConnectedError("XArmGripper.connect(): connect the XArm7 first (the gripper uses its link)")
        check(api, "set_gripper_mode", api.set_gripper_mode(POSITION_MODE))
        check(api, "set_gripper_enable", api.set_gripper_enable(True))
        check(api, "set_gripper_speed", api.set_gripper_speed(self.speed))
        self._connected = True

    def close(self) -> None:
        """Leaves the gripper enabled and holding: disabling it could drop a held object."""
        self._connected = False

    def command(self, width_m: float) -> None:
        api = self._api("command()")
        lo, hi = self.spec.min_width_m, self.spec.max_width_m
        if not math.isfinite(width_m) or not (lo - WIDTH_TOLERANCE_M <= width_m <= hi + WIDTH_TOLERANCE_M):
            raise ValueError(f"gripper width {width_m} m outside the stroke [{lo:.4f}, {hi:.4f}] m")
        position = float(np.clip(round(self.spec.width_to_sdk(width_m)), 0, self.spec.sdk_open))
        check(api, "set_gripper_position", api.set_gripper_position(position, wait=False))
        self._target_sdk = position

    def read_state(self) -> GripperState:
        api = self._api("read_state()")
        position = check(api, "get_gripper_position", api.get_gripper_position())
        error = check(api, "get_gripper_err_code", api.get_gripper_err_code())
        return GripperState(
            self.spec.sdk_to_width(float(position)),
            self.spec.sdk_to_width(self._target_sdk),
            time.monotonic(),
            int(error or 0),
        )

    def stop(self) -> None:
        """Hold the current opening."""
        if not self.is_connected:
            return
        api = self.arm.api
        position = check(api, "get_gripper_position", api.get_gripper_position())
        check(api, "set_gripper_position", api.set_gripper_position(float(position), wait=False))
        self._target_sdk = float(position)
