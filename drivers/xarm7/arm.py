"""UFACTORY xArm 7 on xarm-python-sdk: servo-mode streaming (mode 1) with the state from the 100 Hz report.

The SDK speaks degrees and millimetres; this class is the only place that converts (radians/metres outside).
Every SDK call's code goes through `codes.check`, so the layers above see the typed errors of drivers.errors.
`connect()` is all-or-nothing; `close()` always tries every release step (stop, leave servo mode, disconnect).

The 'real' report carries joint angles, TCP pose, mode and state, but no joint speeds and no error code (the SDK
fills those only from its slower reports or from get_err_warn_code): joint speeds are the difference of
successive reports over the controller's fixed report period, and when a report shows the controller stopped
(state 4) without this driver having stopped it, the error code is asked for once over the command link.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.config import RobotConfig
from drivers.description import RobotSpec, load_robot_spec
from drivers.errors import ArmStoppedError, ControllerError, DeviceNotFoundError, DriverError, NotConnectedError
from drivers.interfaces import Arm
from drivers.types import JointState
from drivers.xarm7 import controller_safety
from drivers.xarm7.codes import check, controller_codes

log = logging.getLogger(__name__)

SERVO_MODE = 1
POSITION_MODE = 0
STOP_STATE = 4
READY_STATES = (0, 1, 2)  # 1 moving, 2 ready/sleeping; 0 just after set_state(0)
READY_TIMEOUT_S = 1.0
REPORT_PERIOD_S = 0.01  # the controller sends the 'real' report at a fixed 100 Hz
STEP_SLACK = 1.5  # the executor keeps steps within safety.max_joint_step_rad; re-timing may exceed it slightly
SDK_THREAD_PRIORITY = 11  # SCHED_FIFO of the SDK's receive threads: just above the executor's streaming thread (10)

ApiFactory = Callable[..., Any]


def sdk_api_factory(ip: str, **kwargs: Any) -> Any:
    """The real XArmAPI (imported here: the SDK is optional and prints its version on import)."""
    with contextlib.redirect_stdout(io.StringIO()):
        from xarm.wrapper import XArmAPI
    # forbid_uds: the SDK would otherwise use a UNIX socket in /tmp named by port only (the controller's own local
    # link), bypassing the configured address
    return XArmAPI(ip, forbid_uds=True, **kwargs)


def prioritise_sdk_threads(api: Any) -> bool:
    """Real-time priority for the SDK's threads that receive replies and the 100 Hz report, when permitted (root
    or CAP_SYS_NICE). The executor stops on a joint state older than 0.1 s: on a loaded PC these normal threads
    were measured 0.1-0.7 s late, behind a streaming thread that has real-time priority. Private SDK attributes
    (xarm-python-sdk 1.18); a report link the SDK re-opens later runs at normal priority again."""
    inner = getattr(api, "_arm", None)
    raised = []
    for name in ("_stream", "_stream_report", "_report_thread"):
        tid = getattr(getattr(inner, name, None), "native_id", None)
        if tid is None:
            continue
        with contextlib.suppress(OSError, AttributeError):
            os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(SDK_THREAD_PRIORITY))
            raised.append(name)
    log.debug("xArm SDK threads at real-time priority: %s", raised or "none (not permitted)")
    return len(raised) == 3


class XArm7(Arm):
    """Servo-mode xArm 7. `safety` is the profile's SafetyConfig: it sets the controller's own limits."""

    def __init__(
        self, robot: RobotConfig, safety: Any, spec: RobotSpec | None = None, api_factory: ApiFactory | None = None
    ) -> None:
        if robot.ip is None:
            raise ValueError("XArm7 needs robot.ip (the controller's IPv4 address)")
        self.config = robot
        self.spec = spec or load_robot_spec()
        self.joint_names = self.spec.joint_names
        self.controller_safety = controller_safety.ControllerSafety.from_profile(robot, safety, self.spec)
        self._factory = api_factory or sdk_api_factory
        self.api: Any = None
        self._stopped = False
        self.firmware_version = ""
        self.max_step_rad = STEP_SLACK * safety.max_joint_step_rad
        self._last_q: np.ndarray | None = None  # last set-point sent; None: compare with the measured position
        self.report_count = 0  # 100 Hz state reports received (report_type 'real')
        self._report_stamp = 0.0  # time.monotonic() of the last one
        self._report_q: np.ndarray | None = None  # joints of the last report [rad]
        self._report_qd = np.zeros(len(self.joint_names))
        self._asked_why_stopped = False  # the error code was read for the current state-4 episode
        self.last_servo_call_s = 0.0

    # -- lifecycle ----------------------------------------------------------------------------------------
    @property
    def is_connected(self) -> bool:
        return self.api is not None

    def connect(self) -> None:
        if self.api is not None:
            return
        ip = str(self.config.ip)
        try:
            api = self._factory(ip, is_radian=False, do_not_open=True, report_type="real")
        except Exception as e:
            raise DriverError(f"xArm SDK could not be set up: {e}") from e
        try:
            api.connect()
        except Exception as e:
            raise DeviceNotFoundError(
                f"no xArm controller answers at {ip} ({e}): check the Ethernet cable, that this PC has an "
                f"address in the robot's subnet, and `ping {ip}`"
            ) from e
        self.api = api
        try:
            api.register_report_callback(
                self._on_report, report_cartesian=False, report_mtable=False, report_mtbrake=False, report_cmd_num=False
            )
            self.firmware_version = str(check(api, "get_version", api.get_version()))
            prioritise_sdk_threads(api)
            self._enable(POSITION_MODE)
            controller_safety.apply(api, self.controller_safety)
            self._enable(SERVO_MODE)
        except BaseException:
            self._release()
            raise
        self._stopped = False
        log.info("xArm 7 at %s connected (firmware %s), servo mode", ip, self.firmware_version)

    def close(self) -> None:
        if self.api is not None:
            self._release()

    def _release(self) -> None:
        """Stop, leave servo mode, disconnect: every step is tried even if an earlier one fails."""
        api, self.api = self.api, None
        steps = (
            ("set_state(4)", lambda: api.set_state(STOP_STATE)),
            ("release_report_callback", lambda: api.release_report_callback(self._on_report)),
            ("set_mode(0)", lambda: api.set_mode(POSITION_MODE)),
            ("set_state(0)", lambda: api.set_state(0)),
            ("disconnect", api.disconnect),
        )
        for name, step in steps:
            try:
                step()
            except Exception as e:
                log.warning("xArm close: %s failed: %s", name, e)

    def _require(self, what: str) -> Any:
        if self.api is None:
            raise NotConnectedError(f"XArm7.{what} before connect() or after close()")
        if not self.api.connected:
            raise NotConnectedError(f"XArm7.{what}: connection to {self.config.ip} lost (check the Ethernet link)")
        return self.api

    # -- enable / fault handling --------------------------------------------------------------------------
    def _enable(self, mode: int) -> None:
        """The vendor's enable sequence, then wait until the controller reports the mode and a ready state."""
        api = self.api
        check(api, "clean_error", api.clean_error())
        check(api, "clean_warn", api.clean_warn())
        check(api, "motion_enable", api.motion_enable(True))
        check(api, "set_mode", api.set_mode(mode))
        check(api, "set_state", api.set_state(0))
        self._last_q = None
        deadline = time.monotonic() + READY_TIMEOUT_S
        while api.mode != mode or api.state not in READY_STATES:
            if time.monotonic() > deadline:
                error, _ = controller_codes(api)
                if error:
                    raise ControllerError(error, "the arm did not enable")
                raise DriverError(
                    f"xArm did not enter mode {mode} (reports mode {api.mode}, state {api.state}) within "
                    f"{READY_TIMEOUT_S} s: check the e-stop and the controller's web UI"
                )
            time.sleep(0.01)

    def clear_fault(self) -> None:
        self._require("clear_fault()")
        self._enable(SERVO_MODE)
        error, _ = controller_codes(self.api)
        if error:
            raise ControllerError(error, "still present after clearing")
        self._stopped = False

    def stop(self) -> None:
        """Software stop (state 4): immediate, no lock, safe from any thread; clear_fault() resumes."""
        self._stopped = True
        api = self.api
        if api is None:
            return
        try:
            api.set_state(STOP_STATE)
        except Exception as e:
            log.error("xArm stop: set_state(4) failed: %s", e)

    def emergency_stop(self) -> None:
        """The SDK's emergency stop (repeats set_state(4) until the controller reports it, up to 3 s)."""
        self._stopped = True
        if self.api is not None:
            self.api.emergency_stop()

    # -- state and commands -------------------------------------------------------------------------------
    def _on_report(self, data: dict) -> None:
        """SDK report thread, 100 Hz: the time of the newest state (the executor stops on a stale one) and the
        joint speeds from the change since the previous report."""
        if "joints" in data:
            q = np.radians(np.asarray(data["joints"], dtype=np.float64)[: len(self.joint_names)])
            if self._report_q is not None:
                self._report_qd = (q - self._report_q) / REPORT_PERIOD_S
            self._report_q = q
        if data.get("state") != STOP_STATE:
            self._asked_why_stopped = False
        self._report_stamp = time.monotonic()
        self.report_count += 1

    def read_state(self) -> JointState:
        """The newest reported state; stamp_s is when it arrived (monotonic), so a silent report link shows as a
        stamp that stops advancing."""
        api = self._require("read_state()")
        n = len(self.joint_names)
        q = np.radians(np.asarray(api.angles, dtype=np.float64)[:n])
        if api.state == STOP_STATE and not self._stopped and not self._asked_why_stopped:
            self._asked_why_stopped = True
            controller_codes(api)  # refreshes api.error_code, which the 'real' report does not carry
        return JointState(self.joint_names, q, self._report_qd.copy(), self._report_stamp, int(api.error_code or 0))

    def servo(self, q: np.ndarray) -> None:
        api = self._require("servo()")
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (len(self.joint_names),) or not np.all(np.isfinite(q)):
            raise ValueError(f"XArm7.servo: need {len(self.joint_names)} finite joint angles [rad], got {q}")
        if self._stopped:
            raise ArmStoppedError("arm is stopped; call clear_fault() to re-enable servo mode")
        if api.error_code:
            raise ControllerError(int(api.error_code), "reported by the controller; call clear_fault()")
        reference = self._last_q if self._last_q is not None else np.radians(np.asarray(api.angles, float)[: len(q)])
        step = np.abs(q - reference)
        if step.max() > self.max_step_rad:  # last line of defence: servo mode executes any jump at full speed
            j = int(np.argmax(step))
            raise ValueError(
                f"XArm7.servo: {self.joint_names[j]} set-point jumps {step[j]:.4f} rad from the last one "
                f"(limit {self.max_step_rad:.4f} rad per tick); refused"
            )
        t0 = time.perf_counter()
        code = api.set_servo_angle_j(np.degrees(q).tolist(), is_radian=False)
        self.last_servo_call_s = time.perf_counter() - t0
        if self.last_servo_call_s > self.config.servo_late_s:
            log.warning("set_servo_angle_j took %.0f ms (late)", 1000 * self.last_servo_call_s)
        if self._stopped:  # stop() arrived while the call was in flight: do not report success
            raise ArmStoppedError("arm was stopped during the servo call; call clear_fault()")
        check(api, "set_servo_angle_j", code)
        self._last_q = q
