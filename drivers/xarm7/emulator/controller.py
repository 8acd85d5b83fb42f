"""The xArm 7 controller's behaviour over the MuJoCo twin: modes, states, errors, controller-side safety, gripper.

What it does is what the real controller shows (hardware-notes.md): servo mode executes the latest set-point at
once (the twin's SimArm: a set-point past a joint limit raises error 23, one implying more than the joint speed
limit raises 24; in reduced mode the reduced joint speed is the limit); with the fence on, a set-point whose TCP
leaves the boundary raises 35; contact that loads a joint above the collision sensitivity's threshold raises 31;
the e-stop button raises 1. An error drops the controller to mode 0 / state 4 with the arm holding, and holds
until clean_error (error 1 comes back while the button is pressed); motion then needs motion_enable, set_mode and
set_state(0). set_state(4) is the software stop (the SDK's emergency_stop repeats it). The TCP pose the controller
reports, and the fence, use the TCP offset that was written to it, not the project's description.

Every set-point is logged (accepted or refused, with why), so tests can check what reached the controller.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.errors import ArmStoppedError, ControllerError
from drivers.sim.arm import CONTROLLER_MAX_JOINT_SPEED, SimArm, SimGripper
from drivers.sim.gl import mujoco
from drivers.sim.world import SimWorld
from drivers.xarm7.emulator.wire import Status

SERVO_MODE = 1
MODES = (0, 1, 2, 4, 5, 6, 7)
MOVING, READY, PAUSED, STOPPED = 1, 2, 3, 4
MOVING_HOLD_S = 0.1  # state 1 (moving) this long after a set-point, then 2 (ready)
ESTOP_BUTTON_ERROR = 1
JOINT_LIMIT_ERROR, SPEED_ERROR, COLLISION_ERROR, FENCE_ERROR = 23, 24, 31, 35
# Joint torque caused by contact [N m] that trips collision detection, per sensitivity 1..5 (0: off). The real
# controller compares measured current with its dynamic model; the twin's contact torques stand in for the residual.
COLLISION_TORQUE_N_M = {1: 40.0, 2: 30.0, 3: 20.0, 4: 14.0, 5: 8.0}
NO_BOUNDARY_MM = (9999.0, -9999.0, 9999.0, -9999.0, 9999.0, -9999.0)
SETPOINTS_KEPT = 200_000  # the journal keeps the last ~30 min at 100 Hz (a standalone emulator runs for hours)
FIRMWARE = "2.7.1"  # the firmware on which the ~200 ms servo-call stall was reported
ROBOT_SN = "XI1303EMULATED"  # xArm 7, a serial number the SDK maps to the standard joint ranges
CONTROL_BOX_SN = "AC1303EMU"  # the version reply is 40 bytes with a terminating NUL: keep it short


@dataclass
class Settings:
    """What the controller has been told (its units: mm, rad), read back by get_reduced_states."""

    collision_sensitivity: int = 3
    collision_tool: int = 0
    self_collision: bool = False
    reduced_mode: bool = False
    fence: bool = False
    collision_rebound: bool = False
    tcp_boundary_mm: tuple[float, ...] = NO_BOUNDARY_MM  # x_max, x_min, y_max, y_min, z_max, z_min
    reduced_tcp_speed_mm_s: float = 1000.0
    reduced_joint_speed_rad_s: float = CONTROLLER_MAX_JOINT_SPEED
    tcp_offset: tuple[float, ...] = (0.0,) * 6  # x, y, z mm, roll, pitch, yaw rad, in the flange frame
    payload_kg: float = 0.0
    payload_cog_mm: tuple[float, ...] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class SetPoint:
    stamp_s: float  # time.monotonic() when it arrived
    q_rad: np.ndarray
    accepted: bool
    reason: str = ""


@dataclass
class Journal:
    """What reached the controller, for tests and the bench."""

    setpoints: deque[SetPoint] = field(default_factory=lambda: deque(maxlen=SETPOINTS_KEPT))
    stops: list[float] = field(default_factory=list)  # time.monotonic() of each set_state(4)
    errors: list[tuple[float, int, str]] = field(default_factory=list)
    stopped: threading.Event = field(default_factory=threading.Event)  # set on every stop or error
    max_contact_torque_n_m: float = 0.0

    def accepted(self) -> list[SetPoint]:
        return [s for s in self.setpoints if s.accepted]


class EmulatedGripper:
    """The xArm Gripper's Modbus registers over the twin's fingers (SDK positions 0 closed .. 850 open)."""

    ENABLE, MODE, RESET_ERROR, SPEED, TARGET, POSITION, ERROR, STATUS = (
        0x0100,
        0x0101,
        0x0109,
        0x0303,
        0x0700,
        0x0702,
        0x000F,
        0x0000,
    )
    VERSION: ClassVar[dict[int, int]] = {0x0801: 3, 0x0802: 4, 0x0803: 3}  # gripper firmware 3.4.3

    def __init__(self, world: SimWorld) -> None:
        self.sim = SimGripper(world)
        self.spec = world.spec.gripper
        self.enabled = False
        self.mode = 0
        self.speed = 0
        self.target = float(self.spec.sdk_open)
        self.commands: list[float] = []  # positions commanded while enabled

    def position(self) -> float:
        return float(self.spec.width_to_sdk(self.sim.read_state().width_m))

    def read_register(self, address: int) -> int:
        if address in (self.POSITION, self.POSITION + 1):
            word = round(self.position()) & 0xFFFFFFFF
            return word >> 16 if address == self.POSITION else word & 0xFFFF
        if address in (self.TARGET, self.TARGET + 1):
            word = round(self.target) & 0xFFFFFFFF
            return word >> 16 if address == self.TARGET else word & 0xFFFF
        return {
            self.ENABLE: int(self.enabled),
            self.MODE: self.mode,
            self.SPEED: self.speed,
            self.ERROR: 0,
            self.STATUS: 0,
            **self.VERSION,
        }.get(address, 0)

    def write_register(self, address: int, value: int) -> None:
        if address == self.ENABLE:
            self.enabled = bool(value)
        elif address == self.MODE:
            self.mode = value
        elif address == self.SPEED:
            self.speed = value
        elif address == self.TARGET and self.enabled:  # a disabled gripper ignores positions
            self.target = float(np.clip(value, 0, self.spec.sdk_open))
            self.commands.append(self.target)
            self.sim.set_position_sdk(self.target)


class ControllerModel:
    """One xArm 7 controller; every method is safe from any connection thread."""

    def __init__(self, world: SimWorld, control_rate_hz: float = 100.0) -> None:
        self.world = world
        self.arm = SimArm(world, control_rate_hz)
        self.gripper = EmulatedGripper(world)
        self.settings = Settings()
        self.journal = Journal()
        self.lock = threading.RLock()
        self.mode, self.state = 0, STOPPED
        self.error, self.warning = 0, 0
        self.enabled = False
        self.estop_pressed = False
        self.cmdnum = 0
        self._last_setpoint_s = -math.inf
        self._fk = mujoco.MjData(world.model)  # scratch data for the TCP of a set-point
        self._flange = world.model.body(world.spec.flange_link).id
        self.version = f"7,7,{ROBOT_SN},{CONTROL_BOX_SN},v{FIRMWARE}"

    def connect(self) -> None:
        """Power on: the twin's arm and gripper come up holding where they are, motors disabled (state 4)."""
        self.arm.connect()
        self.gripper.sim.connect()
        self.arm.stop()

    # -- condition ----------------------------------------------------------------------------------------
    def status(self) -> Status:
        with self.lock:
            s = Status.OK
            if self.error:
                s |= Status.ERROR
            if self.warning:
                s |= Status.WARNING
            if self.state in (STOPPED, 5) or not self.enabled:
                s |= Status.NOT_READY
            return s

    def report_state(self) -> int:
        with self.lock:
            if self.state == READY and time.monotonic() - self._last_setpoint_s < MOVING_HOLD_S:
                return MOVING
            return self.state

    def trip(self, code: int, detail: str) -> None:
        """A controller error: mode 0, state 4, the arm holds; it stays until clean_error."""
        with self.lock:
            if self.error == 0:
                self.journal.errors.append((time.monotonic(), code, detail))
            self.error, self.mode, self.state = code, 0, STOPPED
            self.arm.stop()
            self.journal.stopped.set()

    # -- commands -----------------------------------------------------------------------------------------
    def motion_enable(self, enable: bool) -> None:
        with self.lock:
            self.enabled = enable and not self.estop_pressed
            if not self.enabled:
                self.state = STOPPED
                self.arm.stop()

    def set_mode(self, mode: int) -> bool:
        if mode not in MODES:
            return False
        with self.lock:
            self.mode = mode
            self.state = STOPPED  # the new mode takes effect with set_state(0)
            self.arm.stop()
        return True

    def set_state(self, state: int) -> bool:
        with self.lock:
            if state == 0:
                if self.error or not self.enabled:
                    return True  # refused silently: the reply's status byte says why
                self.state = READY
                self.arm.clear_fault()  # hold where it is; the next set-point is judged from here
            elif state == PAUSED:
                self.state = PAUSED
            elif state == STOPPED:
                self.state = STOPPED
                self.arm.stop()
                self.journal.stops.append(time.monotonic())
                self.journal.stopped.set()
            else:
                return False
        return True

    def clean_error(self) -> None:
        """Clear the error and the twin's fault behind it (else the next tick raised it again before set_state(0)
        could clear it); the arm stays stopped until motion_enable, set_mode and set_state(0)."""
        with self.lock:
            self.error = ESTOP_BUTTON_ERROR if self.estop_pressed else 0
            self.arm.clear_fault()
            self.arm.stop()

    def clean_warn(self) -> None:
        with self.lock:
            self.warning = 0

    def press_estop_button(self) -> None:
        with self.lock:
            self.estop_pressed = True
            self.enabled = False
        self.trip(ESTOP_BUTTON_ERROR, "emergency stop button pressed")

    def release_estop_button(self) -> None:
        with self.lock:
            self.estop_pressed = False

    def servo_j(self, q_rad: np.ndarray) -> None:
        """One servo-mode set-point [rad]: executed at once if the controller is ready, else refused (logged)."""
        with self.lock:
            now = time.monotonic()
            refusal = self._refusal()
            if refusal:
                self.journal.setpoints.append(SetPoint(now, q_rad, False, refusal))
                return
            outside = self._outside_fence(q_rad)
            if outside:
                self.journal.setpoints.append(SetPoint(now, q_rad, False, outside))
                self.trip(FENCE_ERROR, outside)
                return
            self.arm.max_joint_speed_rad_s = self._joint_speed_limit()
            try:
                self.arm.servo(q_rad)
            except ControllerError as e:
                self.journal.setpoints.append(SetPoint(now, q_rad, False, str(e)))
                self.trip(e.code, e.detail)
                return
            except ArmStoppedError as e:
                self.journal.setpoints.append(SetPoint(now, q_rad, False, str(e)))
                return
            self.journal.setpoints.append(SetPoint(now, q_rad, True))
            self._last_setpoint_s = now

    def _refusal(self) -> str:
        if self.error:
            return f"controller error {self.error}"
        if self.mode != SERVO_MODE:
            return f"mode {self.mode}, not servo mode"
        if self.state != READY or not self.enabled:
            return f"state {self.state}, not ready"
        return ""

    def _joint_speed_limit(self) -> float:
        s = self.settings
        return (
            min(CONTROLLER_MAX_JOINT_SPEED, s.reduced_joint_speed_rad_s)
            if s.reduced_mode
            else CONTROLLER_MAX_JOINT_SPEED
        )

    # -- kinematics ---------------------------------------------------------------------------------------
    def _tcp_from_flange(self, xpos: np.ndarray, xmat: np.ndarray) -> np.ndarray:
        T_base_flange = np.eye(4)
        T_base_flange[:3, :3], T_base_flange[:3, 3] = xmat.reshape(3, 3), xpos
        offset = self.settings.tcp_offset
        T_flange_tcp = np.eye(4)
        T_flange_tcp[:3, :3] = Rotation.from_euler("xyz", offset[3:]).as_matrix()
        T_flange_tcp[:3, 3] = np.asarray(offset[:3]) / 1000.0
        return T_base_flange @ T_flange_tcp

    def tcp_of(self, q_rad: np.ndarray) -> np.ndarray:
        """T_base_tcp of a joint vector, with the controller's TCP offset."""
        with self.lock:
            return self._tcp_of(q_rad)

    def _tcp_of(self, q_rad: np.ndarray) -> np.ndarray:
        self._fk.qpos[self.world.arm_qpos] = q_rad
        mujoco.mj_kinematics(self.world.model, self._fk)
        return self._tcp_from_flange(self._fk.xpos[self._flange], self._fk.xmat[self._flange])

    def tcp_pose(self) -> list[float]:
        """The measured TCP as the report carries it: x, y, z [mm], roll, pitch, yaw [rad]."""
        with self.world.lock:
            T = self._tcp_from_flange(self.world.data.xpos[self._flange].copy(), self.world.data.xmat[self._flange])
        return [*(T[:3, 3] * 1000.0), *Rotation.from_matrix(T[:3, :3]).as_euler("xyz")]

    def _outside_fence(self, q_rad: np.ndarray) -> str:
        s = self.settings
        if not s.fence:
            return ""
        p = self._tcp_of(q_rad)[:3, 3] * 1000.0
        x_max, x_min, y_max, y_min, z_max, z_min = s.tcp_boundary_mm
        for axis, value, lo, hi in (("x", p[0], x_min, x_max), ("y", p[1], y_min, y_max), ("z", p[2], z_min, z_max)):
            if not lo <= value <= hi:
                return f"TCP {axis} = {value:.1f} mm outside the fence [{lo:.0f}, {hi:.0f}] mm"
        return ""

    # -- the controller's own cycle (called at the report rate) -------------------------------------------
    def tick(self) -> None:
        """Collision detection on the twin's contact torques, and errors the twin raised by itself (sim.faults)."""
        w = self.world
        with w.lock:
            torque = np.abs(w.data.qfrc_constraint[w.arm_dof])
            twin_fault = self.arm.read_state().fault_code
        peak = float(torque.max())
        with self.lock:
            self.journal.max_contact_torque_n_m = max(self.journal.max_contact_torque_n_m, peak)
            threshold = COLLISION_TORQUE_N_M.get(self.settings.collision_sensitivity)
            active = self.state != STOPPED and not self.error
        if twin_fault and not self.error:
            self.trip(twin_fault, "raised by the twin (sim.faults)")
        elif active and threshold is not None and peak > threshold:
            j = int(np.argmax(torque))
            self.trip(COLLISION_ERROR, f"{w.spec.joint_names[j]} loaded {peak:.1f} N m by contact (> {threshold})")

    def report(self) -> tuple[int, int, int, list[float], list[float], list[float]]:
        """(state, mode, cmdnum, q [rad], TCP pose [mm, rad], joint torques [N m]) for the 'real' report."""
        w = self.world
        with w.lock:
            q = w.data.qpos[w.arm_qpos].tolist()
            torque = w.data.qfrc_actuator[w.arm_dof].tolist()
        with self.lock:
            state, mode, cmdnum = self.report_state(), self.mode, self.cmdnum
        return state, mode, cmdnum, q, self.tcp_pose(), torque
