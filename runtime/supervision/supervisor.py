"""The supervisor: everything that can stop the robot, on threads no stage can block.

- Any sample on the `estop` key stops the arm inside the Zenoh callback itself (no queue, no other thread in
  between), before its payload is even read, then latches ESTOPPED with what the payload said, or what was
  wrong with it: an empty, garbled, oversized, newer or stale e-stop stops the robot like a good one.
- Its own thread, at `WATCH_RATE_HZ`, reads the arm (driver health: fault codes, a driver that stops answering),
  publishes `joint_state` telemetry, enforces each state's time budget and the deadman: while EXECUTING, the
  freshest e-stop node heartbeat must be younger than `deadman_timeout_s`. The deadman judges the e-stop node's
  silence, not this process's: after a stall of this process (a garbage collection or a C call holding the GIL,
  which holds heartbeat callbacks back as well) it waits one heartbeat period for the samples queued meanwhile
  before judging; an arm whose supervisor was stalled could not have been stopped sooner anyway.
- An e-stop node's liveliness token vanishing while EXECUTING stops at once (its process died).
Whatever stops the run sets `cancel`, which the run loop and the executor watch; the supervisor never waits
for them to notice: it has already called arm.stop() itself. `cancel` is set only after the run's end is a
transition of the state machine, so whoever wakes on it (the run record) finds the end recorded. While an
e-stop is stopping the arm, a failure the stop itself causes (the driver refusing set-points) escalates to the
e-stop: the run ends ESTOPPED, never FAILED by its own stop.
"""

from __future__ import annotations

import logging
import threading
import time

from drivers.errors import DriverError
from drivers.interfaces import Arm, Gripper
from runtime.config import RuntimeConfig
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, Event, Heartbeat, JointStateMsg
from runtime.messaging.throttle import Throttle
from runtime.supervision.command_slot import CommandSlot
from runtime.supervision.estop import estop_reason
from runtime.supervision.states import MOVING, TERMINAL, State, StateMachine, Transition

log = logging.getLogger(__name__)

WATCH_RATE_HZ = 200.0
ESTOP_REASON_WAIT_S = 0.5  # a failure caused by an e-stop in flight waits this long at most for the e-stop's reason
MAX_HEARTBEAT_NODES = 32  # e-stop and console nodes tracked at once; a flood of invented names is refused


class Supervisor:
    def __init__(self, machine: StateMachine, bus: Bus, arm: Arm, gripper: Gripper | None, cfg: RuntimeConfig):
        self.machine, self.bus, self.arm, self.gripper, self.cfg = machine, bus, arm, gripper, cfg
        self.cancel = threading.Event()  # set when the current run must end now
        self.commands = CommandSlot()  # run/reset requests for a serving runtime
        self._heartbeats: dict[str, float] = {}  # e-stop node -> monotonic receipt time of its last heartbeat
        self._alive: set[str] = set()
        self._lock = threading.Lock()
        self._estopping: str | None = None  # an e-stop is stopping the arm (its reason) until the next reset
        self._reason_known = threading.Event()  # ... and knows its reason (an e-stop sample: once its payload is read)
        self._notices = Throttle(per_period=5, period_s=1.0)
        self._stop_thread = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="supervisor", daemon=True)
        self.stop_count = 0
        self.graceful_stop = False  # the current run ends by an abort during motion: stop on the path
        machine.add_listener(self._on_transition)
        keys = bus.keys
        bus.subscribe_bytes(keys.estop, self._on_estop_sample)
        bus.subscribe(f"{keys.heartbeat}/**", Heartbeat, self._on_heartbeat)
        bus.subscribe(keys.command, Command, self._on_command)
        bus.watch_liveliness(f"{keys.alive}/estop/**", self._on_liveliness)

    # -- lifecycle ----------------------------------------------------------------------------------------
    def start(self) -> Supervisor:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop_thread.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)

    # -- stopping -----------------------------------------------------------------------------------------
    def halt(self) -> None:
        """Stop arm and gripper now; tries both even if one raises. Safe from any thread."""
        self.stop_count += 1
        for device in (self.arm, self.gripper):
            if device is None:
                continue
            try:
                device.stop()
            except Exception:  # a failing stop must not prevent the next one
                log.exception("stop() of %s failed", type(device).__name__)

    def estop(self, reason: str) -> None:
        """Stop the arm, latch ESTOPPED, then end the run (cancel)."""
        self._stopping(reason, known=True)
        self.halt()
        self._latch(reason)

    def _stopping(self, reason: str, known: bool) -> None:
        with self._lock:
            if self._estopping is None:
                self._estopping = reason
                if known:
                    self._reason_known.set()
                else:
                    self._reason_known.clear()

    def _latch(self, reason: str) -> None:
        with self._lock:
            self._estopping = reason
            self._reason_known.set()
        if self.machine.estop(reason):
            self._event("error", f"E-STOP: {reason}")
        self.cancel.set()

    def fail(self, reason: str, graceful: bool = False) -> None:
        """End the run as FAILED; stops the arm first when it may be moving. `graceful` (operator abort) leaves
        the stop to the run loop, which brings the arm to rest on its path (jerk-limited) and then stops it."""
        if self._estopping is not None:  # an e-stop is under way: this failure is its consequence, the e-stop ends it
            self._reason_known.wait(ESTOP_REASON_WAIT_S)  # (an e-stop sample: once its payload is read)
            with self._lock:
                reason = self._estopping or reason
            self._latch(reason)
            return
        if self.machine.state in MOVING:
            if graceful:
                self.graceful_stop = True
            else:
                self.halt()
        if self.machine.fail(reason):
            self._event("error", reason)
        self.cancel.set()

    def _on_transition(self, t: Transition) -> None:
        if t.state in TERMINAL:
            self.commands.done()  # the run ended: the operator may ask for the next one
        elif t.state == State.IDLE and t.previous == State.ESTOPPED:
            with self._lock:
                self._estopping = None
        elif t.state == State.CAPTURING:
            self.cancel.clear()
            self.graceful_stop = False

    # -- message callbacks (Zenoh threads) ------------------------------------------------------------------
    def _on_estop_sample(self, key: str, payload: bytes) -> None:
        self._stopping(f"e-stop sample on {key}", known=False)
        self.halt()  # first, whatever the payload holds
        try:
            reason = estop_reason(payload)
        except Exception as e:  # the stop must latch even if reading the payload fails in a way nobody foresaw
            reason = f"e-stop sample that could not be read ({type(e).__name__})"
        self._latch(reason)

    def _on_heartbeat(self, key: str, msg: Heartbeat) -> None:
        pattern = f"{self.bus.keys.heartbeat}/**"
        if key != self.bus.keys.heartbeat_of(msg.node):
            self.bus.refuse(pattern, key, f"Heartbeat: node {msg.node!r} does not match its key")
            return
        if msg.kind != "estop":
            return
        now = time.monotonic()
        with self._lock:
            if msg.node not in self._heartbeats and len(self._heartbeats) >= MAX_HEARTBEAT_NODES:
                stale = [n for n, t in self._heartbeats.items() if now - t > 10 * self.cfg.deadman_timeout_s]
                for node in stale:
                    del self._heartbeats[node]
                full = len(self._heartbeats) >= MAX_HEARTBEAT_NODES
            else:
                full = False
            if not full:
                self._heartbeats[msg.node] = now
        if full:
            self.bus.refuse(pattern, key, f"Heartbeat: more than {MAX_HEARTBEAT_NODES} e-stop nodes at once")

    def _on_liveliness(self, key: str, alive: bool) -> None:
        node = key.rsplit("/", 1)[-1]
        with self._lock:
            (self._alive.add if alive else self._alive.discard)(node)
        if not alive:
            with self._lock:
                self._heartbeats.pop(node, None)
            if self.machine.state in MOVING:
                self.estop(f"e-stop node {node} disconnected during execution")

    def _on_command(self, _key: str, cmd: Command) -> None:
        state = self.machine.state
        if cmd.action == "abort":
            if state not in TERMINAL and state != State.IDLE:
                self.fail(f"aborted by the operator (from {cmd.source or 'unknown'})", graceful=True)
            else:
                self.notice(f"abort ignored: no run in progress ({state})")
            return
        refused = self.commands.offer(cmd, state)
        if refused is not None:
            self.notice(refused)

    def notice(self, text: str) -> None:
        """A refusal the operator should see: logged and published as a warning event, a few per second at most."""

        def say(line: str) -> None:
            log.warning(line)
            self._event("warning", line)

        self._notices.tell(text, say)

    # -- deadman ------------------------------------------------------------------------------------------
    def estop_heartbeat_age(self) -> float:
        """Seconds since the freshest e-stop node heartbeat (inf if none)."""
        with self._lock:
            latest = max(self._heartbeats.values(), default=None)
        return float("inf") if latest is None else time.monotonic() - latest

    def deadman_ok(self) -> bool:
        return self.estop_heartbeat_age() <= self.cfg.deadman_timeout_s

    # -- the watch thread ---------------------------------------------------------------------------------
    def _watch(self) -> None:
        period = 1.0 / WATCH_RATE_HZ
        telemetry_period = 1.0 / self.cfg.telemetry_rate_hz
        next_tick = next_telemetry = time.monotonic()
        catch_up_until = 0.0
        while not self._stop_thread.is_set():
            woke = time.monotonic()
            stalled = woke - next_tick
            if stalled > self.cfg.deadman_timeout_s / 4:  # this process stood still: heartbeats queued meanwhile
                catch_up_until = woke + 1.0 / self.cfg.heartbeat_rate_hz
                log.warning("supervisor watch stalled %.3f s (this process, not the e-stop node)", stalled)
            try:
                self._check(publish=time.monotonic() >= next_telemetry, judge_deadman=woke >= catch_up_until)
            except Exception as e:  # the watch must survive anything a device or the bus throws at it
                log.exception("supervisor check failed")
                if self.machine.state in MOVING:  # an unwatched arm must not keep moving
                    self.fail(f"supervisor could not check the arm ({type(e).__name__}: {e})")
            now = time.monotonic()
            if now >= next_telemetry:
                next_telemetry = max(next_telemetry + telemetry_period, now - telemetry_period)
            next_tick = max(next_tick + period, now)
            self._stop_thread.wait(max(0.0, next_tick - time.monotonic()))

    def _check(self, publish: bool, judge_deadman: bool) -> None:
        state = self.machine.state
        if state in MOVING and judge_deadman and not self.deadman_ok():
            self.estop(
                f"deadman: no e-stop node heartbeat for {self.estop_heartbeat_age():.3f} s "
                f"(limit {self.cfg.deadman_timeout_s:.3f} s)"
            )
        overrun = self.machine.overrun()
        if overrun is not None:
            s, spent, budget = overrun
            what = "confirm timeout: no confirmation" if s == State.AWAITING_CONFIRM else f"{s} took too long"
            self.fail(f"{what} ({spent:.1f} s, budget {budget:.1f} s)")
        try:
            js = self.arm.read_state()
        except DriverError as e:
            if state not in TERMINAL and state != State.IDLE:
                self.fail(f"arm driver stopped answering: {e}")
            return
        if js.fault_code and state not in TERMINAL and state != State.IDLE:
            self.fail(f"arm controller error {js.fault_code} during {state}")
        if publish:
            width = None
            if self.gripper is not None:
                try:
                    width = self.gripper.read_state().width_m
                except DriverError:
                    width = None
            msg = JointStateMsg(
                stamp_s=time.time(),
                names=list(js.names),
                q_rad=js.q.tolist(),
                qd_rad_s=js.qd.tolist(),
                fault_code=js.fault_code,
                gripper_width_m=width,
            )
            self.bus.publish(self.bus.keys.joint_state, msg)

    def _event(self, level: str, text: str) -> None:
        try:
            self.bus.publish(self.bus.keys.events, Event(stamp_s=time.time(), level=level, text=text))
        except Exception:
            log.exception("could not publish event %r", text)
