"""Fixed-rate streaming of a gate-approved trajectory to an Arm in servo mode, under supervision.

Servo mode executes the latest set-point at once, so this loop is the whole motion profile: one set-point per
tick on an absolute schedule (no drift), every step checked against the per-tick limit before it is sent, the
measured state checked for freshness, controller faults and tracking error every tick. A late driver call is
survived by skipping the missed ticks and re-timing along the same path from the measured state (PathClock),
never by jumping ahead. abort() stops on the path with a jerk-limited profile; estop() and every fault stop the
arm at once. Only a trajectory approved by the safety gate is accepted.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
from collections import deque
from dataclasses import dataclass

import numpy as np

from drivers.config import RobotConfig
from drivers.interfaces import Arm, Gripper
from motion.approval import ApprovedTrajectory
from motion.clock import Clock, WallClock
from motion.limits import MotionLimits
from motion.pathclock import PathClock
from motion.report import ExecutionReport, GripperOutcome, Jitter, Status
from safety.config import SafetyConfig
from safety.trajectory import GripperEvent, JointTrajectory


class ExecutionRefused(RuntimeError):
    """The trajectory cannot be streamed as given (not approved, wrong rate, far from the arm, ...)."""


@dataclass(frozen=True)
class ExecutorConfig:
    rate_hz: float = 100.0
    max_step_rad: float = 0.04  # largest set-point change per tick
    tracking_error_max_rad: float = 0.05  # distance of the measured position from the recent commands that stops
    tracking_lag_s: float = 0.03  # the measured state may trail the commands by this much (report and servo lag)
    max_state_age_s: float = 0.1  # no new joint state for this long stops the arm
    start_tolerance_rad: float = 0.02  # trajectory start vs measured position
    grasp_margin_m: float = 0.004  # a close ending this much wider than commanded holds an object
    realtime_priority: int | None = 10  # SCHED_FIFO priority of the streaming thread when permitted; None: off

    def __post_init__(self) -> None:
        if not 10.0 <= self.rate_hz <= 250.0:
            raise ValueError(f"rate_hz must be within 10..250 Hz (xArm servo mode), got {self.rate_hz}")

    @classmethod
    def from_configs(cls, robot: RobotConfig, safety: SafetyConfig) -> ExecutorConfig:
        return cls(
            rate_hz=robot.control_rate_hz,
            max_step_rad=safety.max_joint_step_rad,
            tracking_error_max_rad=robot.tracking_error_max_rad,
        )


class _Stop(Exception):
    def __init__(self, status: Status, reason: str) -> None:
        super().__init__(reason)
        self.status, self.reason = status, reason


class Executor:
    """Streams one approved trajectory at a time on its own thread; abort()/estop() may come from any thread."""

    def __init__(
        self,
        arm: Arm,
        config: ExecutorConfig,
        limits: MotionLimits,
        gripper: Gripper | None = None,
        clock: Clock | None = None,
    ) -> None:
        self.arm, self.gripper, self.config, self.limits = arm, gripper, config, limits
        self.clock = clock or WallClock()
        self.period = 1.0 / config.rate_hz
        self._thread: threading.Thread | None = None
        self._report: ExecutionReport | None = None
        self._abort_reason: str | None = None
        self._estop = threading.Event()
        self._estop_reason = ""
        self._send = threading.Lock()

    # -- control from any thread ------------------------------------------------------------------------------
    def abort(self, reason: str = "abort requested") -> None:
        """Stop on the path with a jerk-limited profile (the arm comes to rest on validated positions)."""
        if self._abort_reason is None:
            self._abort_reason = reason

    def estop(self, reason: str = "e-stop") -> None:
        """Stop the arm now: no further set-point is sent after this returns."""
        self._estop_reason = reason
        self._estop.set()  # checked under the send lock: no set-point is sent after this
        self.arm.stop()  # not waiting for an in-flight call; the loop stops the arm again once it returns

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # -- execution --------------------------------------------------------------------------------------------
    def start(self, approved: ApprovedTrajectory) -> None:
        if self.running:
            raise ExecutionRefused("the executor is already streaming a trajectory")
        trajectory = self._check(approved)
        self._report, self._abort_reason = None, None
        self._estop.clear()
        self._thread = threading.Thread(target=self._run, args=(trajectory,), name="motion-executor", daemon=True)
        self._thread.start()

    def wait(self, timeout_s: float | None = None) -> ExecutionReport:
        if self._thread is None:
            raise RuntimeError("nothing was started")
        self._thread.join(timeout_s)
        if self._thread.is_alive():
            raise TimeoutError(f"trajectory still streaming after {timeout_s} s")
        assert self._report is not None
        return self._report

    def execute(self, approved: ApprovedTrajectory) -> ExecutionReport:
        self.start(approved)
        return self.wait()

    def _check(self, approved: ApprovedTrajectory) -> JointTrajectory:
        if not isinstance(approved, ApprovedTrajectory):
            raise ExecutionRefused(f"only a trajectory approved by the safety gate is streamed, got {type(approved)}")
        traj = approved.trajectory
        if abs(traj.dt - self.period) > 1e-9:
            raise ExecutionRefused(f"trajectory dt {traj.dt:.6f} s does not match the control period {self.period} s")
        if tuple(traj.joint_names) != tuple(self.arm.joint_names):
            raise ExecutionRefused(f"trajectory joints {traj.joint_names} are not the arm's {self.arm.joint_names}")
        if traj.gripper_events and self.gripper is None:
            raise ExecutionRefused("the trajectory has gripper events but the executor has no gripper")
        state = self.arm.read_state()
        if state.fault_code:
            raise ExecutionRefused(f"the arm reports controller error {state.fault_code}: clear it first")
        gap = np.abs(traj.positions[0] - state.q)
        if gap.max() > self.config.start_tolerance_rad:
            j = int(np.argmax(gap))
            raise ExecutionRefused(
                f"trajectory starts {gap[j]:.4f} rad from the arm at joint {j + 1} "
                f"(tolerance {self.config.start_tolerance_rad} rad): re-plan from the current state"
            )
        return traj

    def _run(self, traj: JointTrajectory) -> None:
        realtime = False
        if self.config.realtime_priority:
            with contextlib.suppress(OSError, AttributeError):  # needs CAP_SYS_NICE; a normal thread otherwise
                os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(self.config.realtime_priority))
                realtime = True
        loop = _Loop(self, traj)
        try:
            loop.run()
            status, reason = ("aborted", self._abort_reason) if loop.clock.stopping else ("completed", "")
        except _Stop as stop:
            status, reason = stop.status, stop.reason
        except Exception as e:  # driver errors and anything unexpected: stop first, explain after
            status, reason = "fault", f"{type(e).__name__}: {e}"
        if self._estop.is_set():  # a call racing the e-stop may fail (arm stopped): the e-stop is the cause
            status, reason = "estopped", self._estop_reason
        if status in ("fault", "estopped"):
            self._stop_arm()
        self._report = loop.report(status, reason or "", realtime)

    def _stop_arm(self) -> None:
        with contextlib.suppress(Exception):  # best-effort here; the report carries the original fault
            self.arm.stop()


class _Loop:
    """The per-tick work of one execution; raises _Stop to end it."""

    def __init__(self, ex: Executor, traj: JointTrajectory) -> None:
        self.ex, self.traj = ex, traj
        self.clock = PathClock(traj, ex.limits, ex.period)
        self.events = sorted(traj.gripper_events, key=lambda e: e.time_s)
        self.fired: list[GripperEvent] = []
        self.outcomes: list[GripperOutcome] = []
        self.wakes: list[float] = []
        self.taus: list[float] = []
        self.cmds: list[np.ndarray] = []
        self.meas: list[np.ndarray] = []
        self.late_ticks = 0
        self.max_err = 0.0
        self.max_step = 0.0

    def run(self) -> None:
        ex, cfg, clk = self.ex, self.ex.config, self.ex.clock
        state = ex.arm.read_state()
        q_last = state.q.copy()
        recent = deque([q_last], maxlen=max(1, round(cfg.tracking_lag_s * cfg.rate_hz)) + 1)
        stamp, stamp_time = state.stamp_s, clk.now()
        t_next, late = clk.now(), False
        while True:
            clk.sleep_until(t_next)
            now = clk.now()
            if ex._estop.is_set():
                raise _Stop("estopped", ex._estop_reason)
            state = ex.arm.read_state()
            if state.stamp_s != stamp:
                stamp, stamp_time = state.stamp_s, now
            elif now - stamp_time > cfg.max_state_age_s:
                raise _Stop("fault", f"stale joint state: none newer than {now - stamp_time:.3f} s")
            if state.fault_code:
                raise _Stop("fault", f"controller error {state.fault_code}")
            err = min(float(np.max(np.abs(state.q - q))) for q in recent)  # nearest recent set-point
            self.max_err = max(self.max_err, err)
            if err > cfg.tracking_error_max_rad:
                note = ""
                if now - stamp_time > cfg.tracking_lag_s:  # a silent report freezes the measured position: say so
                    note = f" (joint state {1000 * (now - stamp_time):.0f} ms old: the state report stalled)"
                raise _Stop("fault", f"tracking error {err:.4f} rad > {cfg.tracking_error_max_rad} rad{note}")
            if ex._abort_reason is not None:
                self.clock.stop()
            elif late:
                self.clock.retime(state.qd)
            if self.clock.at_rest:
                self._gripper(self.clock.tau)
                return
            tau = self.clock.advance()
            q = self.clock.position(tau)
            step = float(np.max(np.abs(q - q_last)))
            if step > cfg.max_step_rad + 1e-9:
                raise _Stop("fault", f"step {step:.4f} rad at tau={tau:.3f} s exceeds {cfg.max_step_rad} rad per tick")
            self._gripper(tau)
            with ex._send:
                if ex._estop.is_set():
                    raise _Stop("estopped", ex._estop_reason)
                ex.arm.servo(q)
            self.wakes.append(now)
            self.taus.append(tau)
            self.cmds.append(q)
            self.meas.append(state.q)
            self.max_step, q_last = max(self.max_step, step), q
            recent.append(q)
            t_next += ex.period
            after = clk.now()
            late = after > t_next
            if late:  # the call overran into later ticks: skip them rather than catch up with big steps
                self.late_ticks += 1
                t_next += math.ceil((after - t_next) / ex.period) * ex.period

    def _gripper(self, tau: float) -> None:
        """Fire events whose time has come (none once an abort is stopping the arm); judge a close once its hold
        is over."""
        g = self.ex.gripper
        while (
            not self.clock.stopping
            and len(self.fired) < len(self.events)
            and tau >= self.events[len(self.fired)].time_s - 1e-9
        ):
            ev = self.events[len(self.fired)]
            if ev.kind in ("open", "close"):
                g.command(ev.width_m)
            self.fired.append(ev)
            if ev.kind != "close":
                self.outcomes.append(GripperOutcome(ev))
        pending = [e for e in self.fired if e.kind == "close" and all(o.event is not e for o in self.outcomes)]
        for ev in pending:
            if tau >= ev.time_s + ev.duration_s - 1e-9 or self.clock.at_rest:
                width = g.read_state().width_m
                self.outcomes.append(GripperOutcome(ev, width, width > ev.width_m + self.ex.config.grasp_margin_m))

    def report(self, status: Status, reason: str, realtime: bool) -> ExecutionReport:
        dof = len(self.traj.joint_names)
        return ExecutionReport(
            status=status,
            reason=reason,
            ticks=len(self.wakes),
            late_ticks=self.late_ticks,
            jitter=Jitter.of(self.wakes, self.ex.period),
            max_tracking_error_rad=self.max_err,
            realtime_priority=realtime,
            max_step_rad=self.max_step,
            gripper=tuple(self.outcomes),
            times_s=np.array(self.wakes),
            tau_s=np.array(self.taus),
            q_cmd=np.array(self.cmds).reshape(-1, dof),
            q_meas=np.array(self.meas).reshape(-1, dof),
        )
