"""The supervisor: everything that can stop the robot, on threads no stage can block.

- An `estop` message stops the arm inside the Zenoh callback itself (no queue, no other thread in between),
  then latches ESTOPPED.
- Its own thread, at `WATCH_RATE_HZ`, reads the arm (driver health: fault codes, a driver that stops answering),
  publishes `joint_state` telemetry, enforces each state's time budget and the deadman: while EXECUTING, the
  freshest e-stop node heartbeat must be younger than `deadman_timeout_s`.
- An e-stop node's liveliness token vanishing while EXECUTING stops at once (its process died).
Whatever stops the run sets `cancel`, which the run loop and the executor watch; the supervisor never waits
for them to notice: it has already called arm.stop() itself.
"""

from __future__ import annotations

import logging
import threading
import time

from drivers.errors import DriverError
from drivers.interfaces import Arm, Gripper
from runtime.config import RuntimeConfig
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, EStop, Event, Heartbeat, JointStateMsg
from runtime.supervision.states import MOVING, TERMINAL, State, StateMachine, Transition

log = logging.getLogger(__name__)

WATCH_RATE_HZ = 200.0


class Supervisor:
    def __init__(self, machine: StateMachine, bus: Bus, arm: Arm, gripper: Gripper | None, cfg: RuntimeConfig):
        self.machine, self.bus, self.arm, self.gripper, self.cfg = machine, bus, arm, gripper, cfg
        self.cancel = threading.Event()  # set when the current run must end now
        self.commands: list[Command] = []  # run/reset requests for a serving runtime, oldest first
        self.command_ready = threading.Event()
        self._heartbeats: dict[str, float] = {}  # e-stop node -> monotonic receipt time of its last heartbeat
        self._alive: set[str] = set()
        self._lock = threading.Lock()
        self._stop_thread = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="supervisor", daemon=True)
        self.stop_count = 0
        self.graceful_stop = False  # the current run ends by an abort during motion: stop on the path
        machine.add_listener(self._on_transition)
        keys = bus.keys
        bus.subscribe(keys.estop, EStop, self._on_estop)
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
        self.halt()
        self.cancel.set()
        if self.machine.estop(reason):
            self._event("error", f"E-STOP: {reason}")

    def fail(self, reason: str, graceful: bool = False) -> None:
        """End the run as FAILED; stops the arm first when it may be moving. `graceful` (operator abort) leaves
        the stop to the run loop, which brings the arm to rest on its path (jerk-limited) and then stops it."""
        if self.machine.state in MOVING:
            if graceful:
                self.graceful_stop = True
            else:
                self.halt()
        self.cancel.set()
        if self.machine.fail(reason):
            self._event("error", reason)

    def _on_transition(self, t: Transition) -> None:
        if t.state in TERMINAL:
            self.cancel.set()
        elif t.state == State.CAPTURING:
            self.cancel.clear()
            self.graceful_stop = False

    # -- message callbacks (Zenoh threads) ------------------------------------------------------------------
    def _on_estop(self, _key: str, msg: EStop) -> None:
        self.estop(f"{msg.reason} (from {msg.source})")

    def _on_heartbeat(self, _key: str, msg: Heartbeat) -> None:
        if msg.kind == "estop":
            with self._lock:
                self._heartbeats[msg.node] = time.monotonic()

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
        if cmd.action == "abort":
            if self.machine.state not in TERMINAL and self.machine.state != State.IDLE:
                self.fail(f"aborted by the operator (from {cmd.source or 'unknown'})", graceful=True)
            return
        with self._lock:
            self.commands.append(cmd)
        self.command_ready.set()

    def next_command(self) -> Command | None:
        with self._lock:
            cmd = self.commands.pop(0) if self.commands else None
            if not self.commands:
                self.command_ready.clear()
            return cmd

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
        while not self._stop_thread.is_set():
            try:
                self._check(publish=time.monotonic() >= next_telemetry)
            except Exception as e:  # the watch must survive anything a device or the bus throws at it
                log.exception("supervisor check failed")
                if self.machine.state in MOVING:  # an unwatched arm must not keep moving
                    self.fail(f"supervisor could not check the arm ({type(e).__name__}: {e})")
            now = time.monotonic()
            if now >= next_telemetry:
                next_telemetry = max(next_telemetry + telemetry_period, now - telemetry_period)
            next_tick = max(next_tick + period, now)
            self._stop_thread.wait(max(0.0, next_tick - time.monotonic()))

    def _check(self, publish: bool) -> None:
        state = self.machine.state
        if state in MOVING and not self.deadman_ok():
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
