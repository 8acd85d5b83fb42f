"""A fake XArmAPI reproducing the SDK behaviour the driver relies on (hardware-notes.md), failures included.

It records every call, keeps mode/state/error like the controller (errors drop it to state 4; clean_error +
motion_enable + set_mode + set_state(0) recover), returns queued API codes, can refuse the connection, drop the
link (calls then return -1 and `connected` is False) and stall a call until released. Like the real SDK with
report_type 'real' (checked against the emulator in tests/emulator): the report carries joints and state,
`position` is the TCP the controller computes with the offset it was given, set_fence_mode returns [code].
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from typing import Any

import numpy as np


class FakeXArmAPI:
    def __init__(self, port: str, is_radian: bool = False, do_not_open: bool = False, **kwargs: Any) -> None:
        self.init = {"port": port, "is_radian": is_radian, "do_not_open": do_not_open, **kwargs}
        self.calls: list[tuple[str, tuple, dict]] = []
        self.codes: dict[str, list[int]] = defaultdict(list)  # queued return codes per method
        self.stalls: dict[str, threading.Event] = {}  # method -> event the call waits for
        self.stall_started = threading.Event()
        self.refuse_connect = False
        self.connected = False
        self.mode, self.state = 0, 4
        self.error_code, self.warn_code = 0, 0
        self.estop_pressed = False  # error 1 comes back after clean_error while the button is down
        self.angles = [0.0] * 7  # degrees, as the SDK reports with is_radian=False
        self.controller_tcp_offset_mm = [0.0] * 6  # what set_tcp_offset wrote (the SDK cannot read it back)
        self.reduced: list[Any] = [0, [0.0] * 6, 1000.0, 180.0, [], 0, 0]
        self.gripper_position = 850.0
        self.report_callbacks: list = []
        self.report_hz = 100.0  # 0: the report link is silent
        self._reporter: threading.Thread | None = None
        self._ticks = 0  # report periods gone by (a report delivered, or silence)
        self._ticked = threading.Condition()

    # -- helpers ------------------------------------------------------------------------------------------
    def _call(self, name: str, *args: Any, **kwargs: Any) -> int:
        self.calls.append((name, args, kwargs))
        if name in self.stalls:
            self.stall_started.set()
            self.stalls[name].wait(timeout=10)
        if not self.connected:
            return -1
        if self.codes[name]:
            return self.codes[name].pop(0)
        return 0

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]

    def raise_error(self, code: int) -> None:
        """The controller detects an error: it reports it and drops to state 4."""
        self.error_code, self.state = code, 4

    def drop_link(self) -> None:
        self.connected = False

    # -- connection ---------------------------------------------------------------------------------------
    def connect(self) -> None:
        self.calls.append(("connect", (), {}))
        if self.refuse_connect:
            raise Exception("connect socket failed")
        self.connected = True
        self._reporter = threading.Thread(target=self._report_loop, daemon=True)
        self._reporter.start()

    def disconnect(self) -> None:
        self.calls.append(("disconnect", (), {}))
        self.connected = False
        if self._reporter is not None:
            self._reporter.join(timeout=1)

    def _report_loop(self) -> None:
        """The controller's state report (port 30003 with report_type 'real'), delivered to the callbacks."""
        while self.connected:
            if self.report_hz > 0:
                for callback in list(self.report_callbacks):
                    callback({"joints": list(self.angles), "state": self.state})
            with self._ticked:
                self._ticks += 1
                self._ticked.notify_all()
            time.sleep(1.0 / self.report_hz if self.report_hz > 0 else 0.01)  # the report period

    def wait_reports(self, n: int, timeout_s: float = 2.0) -> bool:
        """Block until n more report periods have gone by (each delivered its report to the callbacks, or was
        silent); False on timeout."""
        with self._ticked:
            target = self._ticks + n
            return self._ticked.wait_for(lambda: self._ticks >= target, timeout_s)

    def register_report_callback(self, callback=None, **kwargs: Any) -> bool:
        self.calls.append(("register_report_callback", (callback,), kwargs))
        self.report_callbacks.append(callback)
        return True

    def release_report_callback(self, callback=None) -> bool:
        self.calls.append(("release_report_callback", (callback,), {}))
        if callback in self.report_callbacks:
            self.report_callbacks.remove(callback)
        return True

    def get_version(self) -> tuple[int, str]:
        return self._call("get_version"), "v2.6.0"

    def get_err_warn_code(self, show: bool = False) -> tuple[int, list[int]]:
        return self._call("get_err_warn_code"), [self.error_code, self.warn_code]

    # -- enable sequence ----------------------------------------------------------------------------------
    def clean_error(self) -> int:
        code = self._call("clean_error")
        if code == 0:
            self.error_code = 1 if self.estop_pressed else 0
        return code

    def clean_warn(self) -> int:
        code = self._call("clean_warn")
        if code == 0:
            self.warn_code = 0
        return code

    def motion_enable(self, enable: bool = True) -> int:
        return self._call("motion_enable", enable)

    def set_mode(self, mode: int = 0) -> int:
        code = self._call("set_mode", mode)
        if code == 0:
            self.mode = mode
        return code

    def set_state(self, state: int = 0) -> int:
        code = self._call("set_state", state)
        if code == 0:
            self.state = 2 if state == 0 and not self.error_code else 4
        return code

    def emergency_stop(self) -> None:
        self._call("emergency_stop")
        self.state = 4

    # -- motion -------------------------------------------------------------------------------------------
    def set_servo_angle_j(self, angles: list[float], is_radian: bool | None = None, **kwargs: Any) -> int:
        code = self._call("set_servo_angle_j", list(angles), is_radian=is_radian)
        if code:
            return code
        if self.error_code:
            return 1
        if self.state == 4:
            return 9  # state not ready
        self.angles = list(angles)
        return 0

    # -- controller safety --------------------------------------------------------------------------------
    def set_tcp_offset(self, offset: list[float], is_radian: bool | None = None, wait: bool = True) -> int:
        code = self._call("set_tcp_offset", list(offset), is_radian=is_radian)
        if code == 0:
            self.controller_tcp_offset_mm = list(offset)
        return code

    def set_tcp_load(self, weight: float, center_of_gravity: list[float], wait: bool = False) -> int:
        return self._call("set_tcp_load", weight, list(center_of_gravity))

    def set_collision_sensitivity(self, value: int, wait: bool = True) -> int:
        return self._call("set_collision_sensitivity", value)

    def set_collision_tool_model(self, tool_type: int, *args: Any, **kwargs: Any) -> int:
        return self._call("set_collision_tool_model", tool_type)

    def set_self_collision_detection(self, on_off: bool) -> int:
        return self._call("set_self_collision_detection", on_off)

    def set_reduced_max_joint_speed(self, speed: float, is_radian: bool | None = None) -> int:
        code = self._call("set_reduced_max_joint_speed", speed, is_radian=is_radian)
        if code == 0:
            self.reduced[3] = speed
        return code

    def set_reduced_max_tcp_speed(self, speed: float) -> int:
        code = self._call("set_reduced_max_tcp_speed", speed)
        if code == 0:
            self.reduced[2] = speed
        return code

    def set_reduced_tcp_boundary(self, boundary: list[float]) -> int:
        code = self._call("set_reduced_tcp_boundary", list(boundary))
        if code == 0:
            self.reduced[1] = list(boundary)
        return code

    def set_reduced_mode(self, on: bool) -> int:
        code = self._call("set_reduced_mode", on)
        if code == 0:
            self.reduced[0] = int(on)
        return code

    def set_fence_mode(self, on: bool) -> list[int]:
        code = self._call("set_fence_mode", on)
        if code == 0:
            self.reduced[5] = int(on)
        return [code]  # the SDK returns the raw reply list here, unlike every other setter

    @property
    def position(self) -> list[float]:
        """The TCP the controller reports: its flange pose (the project's model) with the offset it was given."""
        from safety.robot_model import RobotModel

        robot = RobotModel()
        T = robot.frame_pose(np.radians(self.angles), robot.spec.flange_link)
        tcp = T[:3, :3] @ (np.asarray(self.controller_tcp_offset_mm[:3]) / 1000.0) + T[:3, 3]
        return [*(1000.0 * tcp), 0.0, 0.0, 0.0]

    def get_reduced_states(self, is_radian: bool | None = None) -> tuple[int, list[Any]]:
        return self._call("get_reduced_states"), list(self.reduced)

    # -- gripper ------------------------------------------------------------------------------------------
    def set_gripper_mode(self, mode: int) -> int:
        return self._call("set_gripper_mode", mode)

    def set_gripper_enable(self, enable: bool) -> int:
        return self._call("set_gripper_enable", enable)

    def set_gripper_speed(self, speed: int) -> int:
        return self._call("set_gripper_speed", speed)

    def set_gripper_position(self, pos: float, wait: bool = False, **kwargs: Any) -> int:
        code = self._call("set_gripper_position", pos, wait=wait)
        if code == 0:
            self.gripper_position = pos
        return code

    def get_gripper_position(self) -> tuple[int, float]:
        return self._call("get_gripper_position"), self.gripper_position

    def get_gripper_err_code(self) -> tuple[int, int]:
        return self._call("get_gripper_err_code"), 0
