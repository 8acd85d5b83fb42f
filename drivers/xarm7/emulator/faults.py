"""Protocol-level faults, each switchable from a test: the server consults these switches as it serves.

One-shot faults (a stalled or corrupted reply, an action after the n-th set-point, such as a controller error or
a dropped link mid-trajectory) disarm when they fire; every fault that fires is stamped in `fired` (name ->
time.monotonic()) and sets `any_fired`, so a test can wait on the event instead of sleeping.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from drivers.xarm7.emulator.wire import Register

Corruption = Literal["protocol", "truncate"]
STALL_S = 0.2  # the controller's known servo-call stall (hardware-notes.md: ~190 ms about once per 10 s)
TRUNCATED_BYTES = 5  # a truncated reply stops inside the header


@dataclass
class _Armed:
    register: int
    value: object
    count: int = 1


class Faults:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._stall: _Armed | None = None
        self._corrupt: _Armed | None = None
        self._after: tuple[int, Callable[[], None], str] | None = None  # (set-points still to come, action, name)
        self.report_silent = False
        self.refusing = False
        self.fired: dict[str, float] = {}
        self.any_fired = threading.Event()

    def fire(self, name: str) -> None:
        with self._lock:
            self.fired.setdefault(name, time.monotonic())
        self.any_fired.set()

    # -- switches -----------------------------------------------------------------------------------------
    def stall_next(self, seconds: float = STALL_S, register: int = Register.SERVO_J, count: int = 1) -> None:
        """The next `count` replies to `register` come `seconds` late (the command is executed at once)."""
        with self._lock:
            self._stall = _Armed(int(register), seconds, count)

    def corrupt_next(self, how: Corruption = "protocol", register: int = Register.SERVO_J) -> None:
        """The next reply to `register` is malformed: a wrong protocol id, or cut off inside the header."""
        with self._lock:
            self._corrupt = _Armed(int(register), how)

    def after_setpoints(self, setpoints: int, action: Callable[[], None], name: str) -> None:
        """Run `action` (on the serving thread, before the reply) once the n-th set-point from now was executed."""
        if setpoints < 1:
            raise ValueError("after_setpoints needs n >= 1")
        with self._lock:
            self._after = (setpoints, action, name)

    def silence_report(self, silent: bool = True) -> None:
        """The report connection stays open but nothing more is sent on it (or sending resumes)."""
        self.report_silent = silent
        if silent:
            self.fire("report silent")

    # -- consulted by the server ----------------------------------------------------------------------------
    def _take(self, attr: str, register: int) -> object | None:
        with self._lock:
            armed: _Armed | None = getattr(self, attr)
            if armed is None or armed.register != register:
                return None
            armed.count -= 1
            if armed.count <= 0:
                setattr(self, attr, None)
            return armed.value

    def take_stall(self, register: int) -> float:
        seconds = self._take("_stall", register)
        if seconds is None:
            return 0.0
        self.fire("stall")
        return float(seconds)

    def take_corruption(self, register: int) -> Corruption | None:
        how = self._take("_corrupt", register)
        if how is not None:
            self.fire(f"corrupt reply ({how})")
        return how  # type: ignore[return-value]

    def count_setpoint(self) -> None:
        """Called per executed set-point: runs the armed action when its set-point has come."""
        with self._lock:
            if self._after is None:
                return
            left, action, name = self._after
            if left > 1:
                self._after = (left - 1, action, name)
                return
            self._after = None
        self.fire(name)
        action()
