"""Simulated xArm 7 in servo mode and the xArm Gripper.

Like the real controller in mode 1: the latest set-point wins and is tracked at once. A set-point outside the
joint limits, or one implying a joint speed above the controller's limit, raises the controller's error (23,
24) and the arm stops and holds until clear_fault(). Fault hooks: an error at a given sim time, a stalled call.
"""

from __future__ import annotations

import math
import time

import numpy as np

from drivers.errors import ArmStoppedError, ControllerError, NotConnectedError
from drivers.interfaces import Arm, Gripper
from drivers.sim.world import SimWorld
from drivers.types import GripperState, JointState

CONTROLLER_MAX_JOINT_SPEED = math.radians(180.0)  # [rad/s] vendor limit enforced by the controller
SPEED_TOLERANCE = 1.10  # the controller trips a little above its nominal limit


class SimArm(Arm):
    def __init__(self, world: SimWorld, control_rate_hz: float = 100.0) -> None:
        self.world = world
        self.joint_names = world.spec.joint_names
        self._lower, self._upper = world.spec.lower, world.spec.upper
        self._period = 1.0 / control_rate_hz
        self.max_joint_speed_rad_s = CONTROLLER_MAX_JOINT_SPEED  # a controller in reduced mode lowers it
        self._connected = False
        self._stopped = False
        self._fault = 0
        self._last_cmd: np.ndarray | None = None
        self._last_cmd_time = 0.0
        self._error_fired = False
        self._stall_fired = False
        world.add_post_step_hook(self._on_step)

    # -- lifecycle ----------------------------------------------------------------------------------------
    @property
    def is_connected(self) -> bool:
        return self._connected

    def connect(self) -> None:
        if self._connected:
            return
        if self.world.config.realtime:
            self.world.start()
        self._connected = True
        self.clear_fault()

    def close(self) -> None:
        if not self._connected:
            return
        try:
            self.stop()
        finally:
            self._connected = False

    # -- state --------------------------------------------------------------------------------------------
    def _q(self) -> np.ndarray:
        return self.world.data.qpos[self.world.arm_qpos].copy()

    def read_state(self) -> JointState:
        if not self._connected:
            raise NotConnectedError("SimArm.read_state() before connect()")
        w = self.world
        with w.lock:
            return JointState(self.joint_names, self._q(), w.data.qvel[w.arm_dof].copy(), w.time, self._fault)

    # -- commands -----------------------------------------------------------------------------------------
    def _hold(self) -> None:
        """Hold the current position (caller holds the world lock)."""
        self.world.data.ctrl[self.world.arm_act] = self._q()
        self.world.data.ctrl[self.world.arm_vel_act] = 0.0

    def _trip(self, code: int, detail: str) -> ControllerError:
        self._fault = code
        self._hold()
        return ControllerError(code, detail)

    def servo(self, q: np.ndarray) -> None:
        if not self._connected:
            raise NotConnectedError("SimArm.servo() before connect()")
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (len(self.joint_names),) or not np.all(np.isfinite(q)):
            raise ValueError(f"SimArm.servo: need {len(self.joint_names)} finite joint angles, got {q}")
        self._maybe_stall()
        w = self.world
        with w.lock:
            if self._fault:
                raise ControllerError(self._fault, "uncleared; call clear_fault()")
            if self._stopped:
                raise ArmStoppedError("arm is stopped; call clear_fault() to re-enable servo mode")
            outside = (q < self._lower) | (q > self._upper)
            if np.any(outside):
                j = int(np.flatnonzero(outside)[0])
                raise self._trip(
                    23,
                    f"{self.joint_names[j]} set-point {q[j]:.4f} rad outside "
                    f"[{self._lower[j]:.4f}, {self._upper[j]:.4f}]",
                )
            elapsed = max(w.time - self._last_cmd_time, self._period)
            speed = np.abs(q - self._last_cmd) / elapsed
            if np.any(speed > self.max_joint_speed_rad_s * SPEED_TOLERANCE):
                j = int(np.argmax(speed))
                raise self._trip(24, f"{self.joint_names[j]} set-point implies {speed[j]:.2f} rad/s")
            w.data.ctrl[w.arm_act] = q
            w.data.ctrl[w.arm_vel_act] = (q - self._last_cmd) / elapsed
            self._last_cmd = q
            self._last_cmd_time = w.time

    def stop(self) -> None:
        if not self._connected:
            return
        with self.world.lock:
            self._stopped = True
            self._hold()

    def clear_fault(self) -> None:
        if not self._connected:
            raise NotConnectedError("SimArm.clear_fault() before connect()")
        with self.world.lock:
            self._fault = 0
            self._stopped = False
            self._hold()
            self._last_cmd = self._q()
            self._last_cmd_time = self.world.time

    # -- fault hooks --------------------------------------------------------------------------------------
    def _on_step(self) -> None:
        """After each physics step: drop the velocity feed-forward when set-points stop, fire injected faults."""
        w = self.world
        if w.time - self._last_cmd_time > 2 * self._period:
            w.data.ctrl[w.arm_vel_act] = 0.0
        faults = w.config.faults
        if (
            self._connected
            and not self._error_fired
            and faults.arm_error_at_s is not None
            and self.world.time >= faults.arm_error_at_s
        ):
            self._error_fired = True
            self._trip(faults.arm_error_code, "injected fault")

    def _maybe_stall(self) -> None:
        faults = self.world.config.faults
        if not self._stall_fired and faults.servo_stall_at_s is not None and self.world.time >= faults.servo_stall_at_s:
            self._stall_fired = True
            time.sleep(faults.servo_stall_s)  # like a servo call blocking in the real SDK


class SimGripper(Gripper):
    """The xArm Gripper: positions in the SDK's 0 (closed) .. 850 (open) range, widths in metres outside."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world
        self.spec = world.spec.gripper
        self._connected = False
        self._target_sdk = float(self.spec.sdk_open)

    @property
    def is_connected(self) -> bool:
        return self._connected

    def connect(self) -> None:
        if self.world.config.realtime:
            self.world.start()
        self._connected = True

    def close(self) -> None:
        self._connected = False

    def set_position_sdk(self, position: float) -> None:
        """The controller-level command: SDK position 0..850, like XArmAPI.set_gripper_position."""
        if not self._connected:
            raise NotConnectedError("SimGripper command before connect()")
        if not (0 <= position <= self.spec.sdk_open) or not math.isfinite(position):
            raise ValueError(f"gripper position {position} outside the SDK range 0..{self.spec.sdk_open}")
        self._target_sdk = float(position)
        half = self.spec.sdk_to_width(position) / 2
        with self.world.lock:
            self.world.data.ctrl[self.world.finger_act] = half

    def command(self, width_m: float) -> None:
        self.set_position_sdk(round(self.spec.width_to_sdk(width_m)))

    def read_state(self) -> GripperState:
        if not self._connected:
            raise NotConnectedError("SimGripper.read_state() before connect()")
        w = self.world
        with w.lock:
            width = float(np.sum(w.data.qpos[w.finger_qpos]))
            return GripperState(width, self.spec.sdk_to_width(self._target_sdk), w.time)

    def stop(self) -> None:
        """Hold the current opening."""
        if not self._connected:
            return
        w = self.world
        with w.lock:
            w.data.ctrl[w.finger_act] = w.data.qpos[w.finger_qpos]
