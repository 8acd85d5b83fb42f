"""The run loop: one instruction through the states, with the supervisor, recorder and confirm gate around it.

The loop only sequences stages, and goes back in one place: the second look before moving (RECHECKING) may send
it back to REASONING or PLANNING, after which the new plan is confirmed again. Each stage runs on a worker thread
while the loop waits for it or for `cancel` (set by the supervisor on e-stop, abort, fault, deadman or an overrun
budget), so a stuck stage can delay nothing: the run ends when its time is up and the arm has already been
stopped by the supervisor.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import traceback
import uuid
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Literal

from drivers.errors import DriverError
from drivers.sim.gl import release_context
from runtime.config import Profile
from runtime.devices import Devices
from runtime.messaging.bus import Bus
from runtime.messaging.messages import PlanSummary
from runtime.run.context import RunContext, StageError, Stages
from runtime.run.gc_pauses import collector_pauses_held_off
from runtime.run.record import RunRecord, publish_image, to_bgr
from runtime.run.summary import ConfirmationRecord, RunSummary
from runtime.supervision.confirm import ConfirmGate
from runtime.supervision.estop import EStopNode
from runtime.supervision.estop_latch import EStopLatch
from runtime.supervision.states import TERMINAL, State, StateMachine, Transition, TransitionError
from runtime.supervision.status import StatusPublisher
from runtime.supervision.supervisor import Supervisor

log = logging.getLogger(__name__)

ConfirmMode = Literal["yes", "prompt", "console"]
PIPELINE = (
    (State.CAPTURING, "capture"),
    (State.REASONING, "reason"),
    (State.GROUNDING, "ground"),
    (State.PLANNING, "plan"),
)


STAGE_GRACE_S = 3.0  # on close, how long a still-running stage may take to return


class Cancelled(Exception):
    """The supervisor ended the run while a stage was working."""


@dataclass(frozen=True)
class RunResult:
    status: State
    reason: str
    run_dir: Path
    summary: RunSummary

    @property
    def ok(self) -> bool:
        return self.status == State.DONE


class Runtime:
    """The runtime node: owns the bus session (it listens), the state machine and the safety collaborators."""

    def __init__(
        self,
        profile: Profile,
        devices: Devices,
        stages: Stages,
        confirm: ConfirmMode = "console",
        prompt: Callable[[PlanSummary], bool] | None = None,
    ) -> None:
        cfg = profile.runtime
        if cfg.estop_node == "in_process" and not profile.robot.simulated:
            raise ValueError(
                f"runtime.estop_node 'in_process' is for the sim only; robot.kind is {profile.robot.kind!r}: "
                "run `goalvla estop` on a terminal next to the robot"
            )
        self.profile, self.devices, self.stages = profile, devices, stages
        self.confirm_mode, self.prompt = confirm, prompt
        self.bus = Bus(cfg.zenoh, cfg.robot_id, "listen")
        self.machine = StateMachine(cfg.budgets_s)
        self.status = StatusPublisher(self.bus, self.machine).start()
        self.supervisor = Supervisor(self.machine, self.bus, devices.arm, devices.gripper, cfg).start()
        self.confirm_gate = ConfirmGate(self.bus, self.supervisor.notice)
        self.estop_node = (
            EStopNode(self.bus, "in_process", cfg.heartbeat_rate_hz).start()
            if (cfg.estop_node == "in_process")
            else None
        )
        self.arm_halted = False  # the last run stopped the arm mid-way: Reset before the next run
        self.latch = EStopLatch(cfg.estop_latch_file) if cfg.estop_latch_file is not None else None
        if self.latch is not None:
            latched = self.latch.engaged()
            if latched is not None:
                self.machine.estop(f"{latched.describe()}; check the cell, then reset (goalvla reset, or the console)")
            self.machine.add_listener(self._latch_estop)
        # One long-lived thread runs every stage: device handles that are bound to a thread (the sim camera's GL
        # context) stay on it, and the run loop only waits on it, so it can give up on a stuck stage.
        self._stage_thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stage")
        self._pending: Future | None = None
        if profile.camera.kind == "sim":
            release_context()  # the camera was opened (and its context bound) on this thread

    # -- lifecycle ----------------------------------------------------------------------------------------
    def close(self) -> None:
        if self.estop_node is not None:
            self.estop_node.close()
        self.supervisor.close()
        self.status.close()
        self.supervisor.halt()
        if self._pending is not None:
            with contextlib.suppress(Exception):  # a stuck stage gets a last chance to return
                self._pending.result(timeout=STAGE_GRACE_S)
        if self.profile.camera.kind == "sim" and (self._pending is None or self._pending.done()):
            self._stage_thread.submit(release_context).result(timeout=1.0)  # the camera closes on another thread
        self._stage_thread.shutdown(wait=False, cancel_futures=True)
        self.bus.close()

    def __enter__(self) -> Runtime:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _latch_estop(self, transition: Transition) -> None:
        if transition.state == State.ESTOPPED and self.latch.engaged() is None:
            self.latch.engage(transition.reason, transition.stamp_s)

    def reset(self, source: str = "operator") -> None:
        """Leave ESTOPPED/FAILED after a person checked the cell: clears controller faults, back to IDLE."""
        self.machine.reset(f"reset by {source}")
        if self.latch is not None:
            self.latch.release(source)
        self.devices.arm.clear_fault()
        self.arm_halted = False
        self.status.event(f"reset by {source}")

    # -- one run ------------------------------------------------------------------------------------------
    def run(self, instruction: str, run_dir: Path | None = None) -> RunResult:
        run_id = datetime.now(UTC).strftime("%Y%m%d-%H%M%S-") + uuid.uuid4().hex[:6]
        run_dir = run_dir or self.profile.runtime.runs_dir / run_id
        record = RunRecord(run_dir, run_id, self.bus)
        summary = record.summary
        summary.instruction, summary.profile = instruction, self.profile.name
        summary.robot_id = self.profile.runtime.robot_id
        if self.profile.robot.simulated:
            summary.scene, summary.seed = self.profile.sim.scene, self.profile.sim.seed
        self.status.run_id, self.status.plan_id, self.status.instruction = run_id, "", instruction
        ctx = RunContext(self.profile, self.devices, instruction, record, self.supervisor.cancel)
        self.machine.add_listener(record.on_transition)
        try:
            self._sequence(ctx)
        except Cancelled:
            pass  # the supervisor already ended the run with its reason
        except KeyboardInterrupt:
            self.supervisor.estop("interrupted (Ctrl-C) in goalvla run")
        except TransitionError as e:
            if self.machine.state not in (State.FAILED, State.ESTOPPED):
                self.supervisor.fail(str(e))
        finally:
            self.machine.remove_listener(record.on_transition)
            self._end_motion(ctx)
        state, reason = self.machine.state, self.machine.reason
        record.finish(state.value, reason, ctx)
        return RunResult(state, reason, run_dir, record.summary)

    def _sequence(self, ctx: RunContext) -> None:
        if self.arm_halted:
            self.machine.advance(State.CAPTURING, "run requested")
            raise self._fail("the previous run stopped the arm mid-way: press Reset after checking the cell")
        for state, name in PIPELINE:
            self._stage(state, name, ctx)
        replans = 0
        while True:
            self._confirm(ctx)
            back = self._second_look(ctx, replans)
            if back is None:
                break
            replans += 1
            for state, name in PIPELINE[[s for s, _ in PIPELINE].index(back) :]:  # from there on again
                self._stage(state, name, ctx, entered=state == back)
        if not self.supervisor.deadman_ok():
            age = self.supervisor.estop_heartbeat_age()
            raise self._fail(
                f"no fresh e-stop heartbeat (last {age:.2f} s ago, limit {self.profile.runtime.deadman_timeout_s} s):"
                " start `goalvla estop` and keep it running"
            )
        self._stage(State.EXECUTING, "execute", ctx)
        self.machine.advance(State.VERIFYING)
        verdict = self._call(self.stages.verify, ctx, "verify")
        ctx.record.summary.verification = verdict
        if verdict.ok:
            self.machine.advance(State.DONE, verdict.reason)
        else:
            raise self._fail(f"verify: {verdict.reason}")

    def _confirm(self, ctx: RunContext) -> None:
        """The operator approves the plan planning made, by its id, or the run ends."""
        plan = ctx.plan
        if plan is None:
            raise self._fail("planning produced no plan summary")
        self.status.plan_id = plan.plan_id
        ctx.record.summary.plan = plan
        self.confirm_gate.expect(plan.plan_id)
        self.machine.advance(State.AWAITING_CONFIRM, f"plan {plan.plan_id}")
        self.bus.publish(self.bus.keys.plan, plan)
        self._ask_confirmation(plan)
        decision = self.confirm_gate.wait(ctx.cancel)
        if decision is None:
            raise Cancelled
        ctx.record.summary.confirmation = ConfirmationRecord(source=decision.source, approved=decision.approve)
        if not decision.approve:
            raise self._fail(f"plan {plan.plan_id} declined by {decision.source}")

    def _second_look(self, ctx: RunContext, replans: int) -> State | None:
        """RECHECKING: look again right before moving. None when the confirmed plan still holds, else the state
        the run goes back to (bounded by runtime.second_look.max_replans, beyond which it refuses)."""
        cfg = self.profile.runtime.second_look
        if not cfg.enabled:
            self.machine.advance(State.RECHECKING, "second look off (runtime.second_look.enabled)")
            return None
        self.machine.advance(State.RECHECKING)
        look = self._call(self.stages.recheck, ctx, "recheck")
        ctx.record.summary.second_look.append(look)
        if look.decision == "still":
            return None
        if replans >= cfg.max_replans:
            raise self._fail(
                f"recheck: {look.reason}; the scene changed after {replans} replan(s) already "
                f"(runtime.second_look.max_replans {cfg.max_replans}): not moving in a scene that does not hold still"
            )
        back = State.PLANNING if look.decision == "replan" else State.REASONING
        self.machine.back(back, look.reason)
        return back

    def _ask_confirmation(self, plan: PlanSummary) -> None:
        if self.confirm_mode == "yes":
            self.confirm_gate.send(plan.plan_id, "cli --yes")
        elif self.confirm_mode == "prompt" and self.prompt is not None:

            def ask() -> None:
                approve = self.prompt(plan)
                if self.machine.state == State.AWAITING_CONFIRM:
                    self.confirm_gate.send(plan.plan_id, "terminal", approve)

            threading.Thread(target=ask, name="confirm-prompt", daemon=True).start()

    def _fail(self, reason: str) -> Cancelled:
        self.supervisor.fail(reason)
        return Cancelled()

    def _stage(self, state: State, name: str, ctx: RunContext, entered: bool = False) -> None:
        if not entered:
            self.machine.advance(state)
        if state == State.EXECUTING:
            ctx.executing = True  # from here on, a run that ends badly must stop the motion
        with collector_pauses_held_off() if state == State.EXECUTING else contextlib.nullcontext():
            result = self._call(getattr(self.stages, name), ctx, name)
        if state == State.PLANNING:
            ctx.plan = result

    def _call(self, fn: Callable, ctx: RunContext, name: str):
        """Run a stage on the stage thread; return its result, or end the run on refusal, error or cancel."""
        if self._pending is not None and not self._pending.done():
            wait([self._pending], timeout=STAGE_GRACE_S)  # a camera preview, or a stage finishing late
        if self._pending is not None and not self._pending.done():
            raise self._fail(f"{name}: a stage of an earlier run is still running (stuck backend?): restart")
        future = self._pending = self._stage_thread.submit(fn, ctx)
        while not wait([future], timeout=0.01).done:  # (a stage's own TimeoutError must not look like ours)
            if ctx.cancel.is_set():
                raise Cancelled
        if ctx.cancel.is_set():
            raise Cancelled
        try:
            return future.result()
        except StageError as e:
            raise self._fail(f"{name}: {e}") from e
        except DriverError as e:
            raise self._fail(f"{name}: {type(e).__name__}: {e}") from e
        except Exception as e:
            (ctx.record.dir / "error.txt").write_text("".join(traceback.format_exception(e)))
            log.error("stage %s raised", name, exc_info=e)
            raise self._fail(f"{name}: unexpected {type(e).__name__}: {e} (traceback in error.txt)") from e

    def _end_motion(self, ctx: RunContext) -> None:
        """After a run that did not finish cleanly nothing may keep moving: the executor is stopped (on its path
        for an operator abort, at once otherwise) and the arm and gripper are stopped in every case."""
        if self.machine.state == State.DONE:
            return
        if not ctx.executing and self.machine.state != State.ESTOPPED:
            return
        graceful = self.supervisor.graceful_stop and self.machine.state == State.FAILED
        try:
            self.stages.stop_motion(ctx, self.machine.reason, graceful)
        except Exception:
            log.exception("stop_motion failed")
        self.supervisor.halt()
        self.arm_halted = True

    # -- serving the console ------------------------------------------------------------------------------

    def preview(self) -> None:
        """Between runs, the latest camera frame for the console (on the stage thread, which owns the camera)."""
        if self.machine.state not in (State.IDLE, *TERMINAL) or (self._pending and not self._pending.done()):
            return

        def grab() -> None:
            frame = self.devices.camera.read(self.profile.camera.read_timeout_s)
            publish_image(self.bus, "capture", to_bgr(frame.rgb))

        self._pending = self._stage_thread.submit(grab)
