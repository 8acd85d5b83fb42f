"""A scripted stand-in for the Goal-VLA pipeline, for testing the runtime around it (not the method).

Capture is real (sim camera); reasoning and grounding return fixed results or the fault a test asks for;
planning makes a smooth joint move from where the arm is; execution streams it tick by tick at the control
rate; verification checks where the arm ended. The runtime's supervision, confirm gate and records are what
the tests exercise.
"""

from __future__ import annotations

import threading
import time
import uuid

import numpy as np

from motion.interpolate import minimum_jerk_path
from runtime.messaging.messages import PlanSummary
from runtime.run.context import RunContext, StageError, Verification

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
        self._stop = threading.Event()

    def capture(self, ctx: RunContext) -> None:
        dev = ctx.devices
        ctx.frame0 = dev.capture(ctx.profile.camera.read_timeout_s)
        ctx.record.image("capture", ctx.frame0.rgb)

    def reason(self, ctx: RunContext) -> None:
        if self.reason_error is not None:
            raise self.reason_error
        time.sleep(self.reason_delay_s)
        ctx.goal = {"instruction": ctx.instruction}

    def ground(self, ctx: RunContext) -> None:
        if self.ground_error:
            raise StageError(self.ground_error)
        ctx.motion = {"translation_m": [0.0, 0.1, 0.0]}

    def plan(self, ctx: RunContext) -> PlanSummary:
        q0 = ctx.devices.arm.read_state().q
        rate = ctx.profile.robot.control_rate_hz
        path = np.vstack([q0, minimum_jerk_path(q0, q0 + MOVE_RAD, rate, self.move_speed)])
        ctx.trajectory = path
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

    def execute(self, ctx: RunContext) -> None:
        arm, period = ctx.devices.arm, 1.0 / ctx.profile.robot.control_rate_hz
        self._stop.clear()
        self.executing.set()
        t_next = time.monotonic()
        for q in ctx.trajectory[1:]:
            if self._stop.is_set():
                return
            arm.servo(q)
            self.streamed += 1
            t_next += period
            time.sleep(max(0.0, t_next - time.monotonic()))

    def verify(self, ctx: RunContext) -> Verification:
        time.sleep(0.3)
        err = float(np.max(np.abs(ctx.devices.arm.read_state().q - ctx.trajectory[-1])))
        return Verification(err < 0.02, f"arm within {err:.4f} rad of the goal", position_error_m=None)

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        self._stop.set()
