"""A scripted stand-in for the Goal-VLA pipeline, for testing the runtime around it (not the method).

Capture is real (sim camera); reasoning and grounding do nothing or raise the fault a test asks for;
planning makes a smooth joint move from where the arm is; execution streams it tick by tick at the control
rate, and an operator's abort (graceful stop_motion) brings it to rest on that path with a ramp down;
verification checks where the arm ended. The runtime's supervision, confirm gate and records are what
the tests exercise.
"""

from __future__ import annotations

import threading
import time
import uuid

import numpy as np

from motion.interpolate import minimum_jerk_path
from runtime.messaging.messages import PlanSummary
from runtime.run.context import RunContext, StageError
from runtime.run.summary import LookRecord, Verification

MOVE_RAD = np.array([0.35, 0.25, 0.0, -0.25, 0.0, 0.2, 0.35])


class ScriptedStages:
    def __init__(
        self,
        move_speed_rad_s: float = 0.25,
        reason_delay_s: float = 0.0,
        ground_error: str = "",
        reason_error: Exception | None = None,
    ) -> None:
        self.move_speed = move_speed_rad_s
        self.reason_delay_s = reason_delay_s
        self.ground_error = ground_error
        self.reason_error = reason_error
        self.executing = threading.Event()
        self.streamed = 0
        self.planned = 0
        self.path = np.empty((0, 7))
        self.stops: list[tuple[str, bool]] = []  # stop_motion's (reason, graceful), in order
        self.ramp: list[np.ndarray] = []  # set-points sent coming to rest after a graceful stop
        self._stop = threading.Event()
        self._done = threading.Event()  # execute returned (at the end of the path, or at rest after a stop)
        self._graceful = False

    def capture(self, ctx: RunContext) -> None:
        dev = ctx.devices
        ctx.frame0 = dev.capture(ctx.profile.camera.read_timeout_s)
        ctx.record.image("capture", ctx.frame0.rgb)

    def reason(self, ctx: RunContext) -> None:
        if self.reason_error is not None:
            raise self.reason_error
        time.sleep(self.reason_delay_s)  # a slow backend (the budget test cuts it off)

    def ground(self, ctx: RunContext) -> None:
        if self.ground_error:
            raise StageError(self.ground_error)

    def plan(self, ctx: RunContext) -> PlanSummary:
        q0 = ctx.devices.arm.read_state().q
        rate = ctx.profile.robot.control_rate_hz
        path = np.vstack([q0, minimum_jerk_path(q0, q0 + MOVE_RAD, rate, self.move_speed)])
        self.path = path
        self.planned = len(path)
        speeds = np.abs(np.diff(path, axis=0)).max(axis=0) * rate
        return PlanSummary(
            stamp_s=time.time(),
            plan_id=uuid.uuid4().hex[:8],
            run_id=ctx.record.run_id,
            instruction=ctx.instruction,
            mode="scripted",
            duration_s=(len(path) - 1) / rate,
            peak_joint_speed_rad_s=speeds.tolist(),
            samples=len(path),
            gate_ok=True,
        )

    def recheck(self, ctx: RunContext) -> LookRecord:
        return LookRecord(capture="look", compared_with=ctx.basis, changes=[], decision="still", reason="", seconds=0.0)

    def execute(self, ctx: RunContext) -> None:
        arm, period = ctx.devices.arm, 1.0 / ctx.profile.robot.control_rate_hz
        self._stop.clear()
        self._done.clear()
        self.executing.set()
        t_next = time.monotonic()
        try:
            for k in range(1, len(self.path)):
                if self._stop.is_set():
                    if self._graceful:
                        self._come_to_rest(arm, k, t_next, period)
                    return
                arm.servo(self.path[k])
                self.streamed += 1
                t_next += period
                time.sleep(max(0.0, t_next - time.monotonic()))  # the control rate
        finally:
            self._done.set()

    def _come_to_rest(self, arm, k: int, t_next: float, period: float) -> None:
        """Slow down along the path: each step a fraction smaller than the last, until the steps are tiny."""
        s, step = float(k - 1), 1.0
        while step > 0.02 and s + step < len(self.path) - 1:
            s, step = s + step, step * 0.85
            i = int(s)
            q = self.path[i] + (s - i) * (self.path[i + 1] - self.path[i])
            arm.servo(q)
            self.ramp.append(q)
            t_next += period
            time.sleep(max(0.0, t_next - time.monotonic()))  # the control rate

    def verify(self, ctx: RunContext) -> Verification:
        deadline = time.monotonic() + 1.0  # the simulated arm settles on its last set-point
        while (err := self._error(ctx)) >= 0.02 and time.monotonic() < deadline:
            time.sleep(0.01)
        return Verification(ok=err < 0.02, reason=f"arm within {err:.4f} rad of the goal")

    def _error(self, ctx: RunContext) -> float:
        return float(np.max(np.abs(ctx.devices.arm.read_state().q - self.path[-1])))

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        """Graceful: returns once the ramp down is sent (bounded, like the executor's abort)."""
        self.stops.append((reason, graceful))
        self._graceful = graceful
        self._stop.set()
        if graceful:
            self._done.wait(2.0)
