"""The supervisor stops the arm on e-stop, deadman loss, node death, faults and budget overruns."""

from __future__ import annotations

import time

import pytest
from runtime_helpers import RecordingArm, wait_for

from runtime.config import StateBudgets
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, JointStateMsg
from runtime.supervision.estop import EStopNode
from runtime.supervision.states import State, StateMachine
from runtime.supervision.supervisor import Supervisor

TO_EXECUTING = (
    State.CAPTURING,
    State.REASONING,
    State.GROUNDING,
    State.PLANNING,
    State.AWAITING_CONFIRM,
    State.RECHECKING,
)


@pytest.fixture
def rig(runtime_cfg):
    hub = Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "listen")
    node_bus = Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "connect")
    arm = RecordingArm()
    machine = StateMachine(runtime_cfg.budgets_s)
    sup = Supervisor(machine, hub, arm, None, runtime_cfg).start()
    node = EStopNode(node_bus, "pendant", runtime_cfg.heartbeat_rate_hz).start()
    assert wait_for(sup.deadman_ok), "no heartbeat from the e-stop node"
    yield sup, machine, arm, node, node_bus
    node.close()
    sup.close()
    node_bus.close()
    hub.close()


def _to_executing(machine: StateMachine) -> None:
    for s in TO_EXECUTING:
        machine.advance(s)
    machine.advance(State.EXECUTING)


def test_estop_message_stops_the_arm_and_latches(rig):
    sup, machine, arm, node, _ = rig
    _to_executing(machine)
    node.press("test button")
    assert wait_for(arm.stopped.is_set, 1.0)
    assert wait_for(sup.cancel.is_set, 1.0)  # set last, once the end is latched: the arm stops before
    assert machine.state == State.ESTOPPED and "test button (from pendant)" in machine.reason


def test_estop_when_idle_still_latches(rig):
    _sup, machine, arm, node, _ = rig
    node.press()
    assert wait_for(lambda: machine.state == State.ESTOPPED)
    assert arm.stopped.is_set()


def test_frozen_node_trips_the_deadman_during_execution(rig):
    _sup, machine, arm, node, _ = rig
    _to_executing(machine)
    t0 = time.monotonic()
    node.paused.set()
    assert wait_for(lambda: machine.state == State.ESTOPPED, 2.0)
    assert time.monotonic() - t0 < 0.2 + 0.2  # deadman 0.2 s, watch at 200 Hz (slack for a loaded machine)
    assert "deadman" in machine.reason and arm.stopped.is_set()


def hold_the_gil(seconds: float) -> float:
    """Stand this whole process still for at least `seconds`, as a full garbage collection does: sum() over a range
    runs in C with the GIL held, so no other Python thread (heartbeats, their callbacks, the watch) runs meanwhile."""
    t0 = time.monotonic()
    sum(range(100_000))
    n = int(100_000 * seconds / max(time.monotonic() - t0, 1e-6) * 1.5)
    t0 = time.monotonic()
    sum(range(n))
    return time.monotonic() - t0


def checks_after(node_bus, count: int = 3) -> bool:
    """True once the watch has run `count` more checks (each joint_state it publishes comes after one)."""
    checks = []
    node_bus.subscribe(node_bus.keys.joint_state, JointStateMsg, lambda k, m: checks.append(m))
    return wait_for(lambda: len(checks) >= count, 2.0)


def test_a_stall_of_this_process_does_not_trip_the_deadman(rig):
    """A stall longer than the deadman timeout holds back the e-stop node's heartbeats (in this test the node is in
    the same process) and their callbacks: it is this process that stood still, not the node, and the run goes on."""
    sup, machine, arm, _node, node_bus = rig
    _to_executing(machine)
    held = hold_the_gil(0.3)
    stall_ended = time.monotonic()
    assert held > 0.2  # longer than the deadman timeout
    assert wait_for(lambda: sup.estop_heartbeat_age() < time.monotonic() - stall_ended, 2.0)  # a beat since
    assert checks_after(node_bus)
    assert machine.state == State.EXECUTING, machine.reason
    assert not arm.stopped.is_set()


def test_a_node_that_froze_during_a_stall_of_this_process_trips_the_deadman(rig):
    _sup, machine, arm, node, _ = rig
    _to_executing(machine)
    node.paused.set()
    assert hold_the_gil(0.3) > 0.2
    stall_ended = time.monotonic()
    assert wait_for(lambda: machine.state == State.ESTOPPED, 2.0)
    assert time.monotonic() - stall_ended < 0.05 + 0.2  # one heartbeat period of catch-up (slack for a loaded machine)
    assert "deadman" in machine.reason and arm.stopped.is_set()


def test_frozen_node_outside_execution_does_not_stop(rig):
    sup, machine, arm, node, node_bus = rig
    machine.advance(State.CAPTURING)
    node.paused.set()
    assert wait_for(lambda: not sup.deadman_ok(), 2.0)
    # the watch has judged the stale deadman since: each joint_state it publishes comes after a check
    checks = []
    node_bus.subscribe(node_bus.keys.joint_state, JointStateMsg, lambda k, m: checks.append(m))
    assert wait_for(lambda: len(checks) >= 3, 2.0)
    assert machine.state == State.CAPTURING and not sup.deadman_ok()
    assert not arm.stopped.is_set()


def test_node_process_gone_stops_at_once(rig):
    _sup, machine, arm, node, node_bus = rig
    _to_executing(machine)
    node.close()
    node_bus.close()  # the token vanishes with the session
    assert wait_for(lambda: machine.state == State.ESTOPPED, 1.0)
    assert arm.stopped.is_set()


def test_controller_fault_fails_the_run_and_stops(rig):
    _sup, machine, arm, _node, _ = rig
    _to_executing(machine)
    arm.fault_code = 31
    assert wait_for(lambda: machine.state == State.FAILED)
    assert "controller error 31" in machine.reason and arm.stopped.is_set()


def test_driver_silence_fails_the_run(rig):
    _sup, machine, arm, _node, _ = rig
    machine.advance(State.CAPTURING)
    arm.broken = True
    assert wait_for(lambda: machine.state == State.FAILED)
    assert "stopped answering" in machine.reason


def test_budget_overrun_fails_with_the_numbers(runtime_cfg):
    cfg = runtime_cfg.model_copy(update={"budgets_s": StateBudgets(reasoning=0.1)})
    with Bus(cfg.zenoh, cfg.robot_id, "listen") as hub:
        machine = StateMachine(cfg.budgets_s)
        sup = Supervisor(machine, hub, RecordingArm(), None, cfg).start()
        machine.advance(State.CAPTURING)
        machine.advance(State.REASONING)
        assert wait_for(lambda: machine.state == State.FAILED)
        assert "REASONING took too long" in machine.reason and "budget 0.1 s" in machine.reason
        sup.close()


def test_abort_command_and_telemetry_rate(rig):
    _sup, machine, arm, _node, node_bus = rig
    stamps = []
    node_bus.subscribe(node_bus.keys.joint_state, JointStateMsg, lambda k, m: stamps.append(time.monotonic()))
    assert wait_for(lambda: len(stamps) >= 51, 3.0)
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    assert rate >= 45.0, f"joint_state at {rate:.1f} Hz"
    _to_executing(machine)
    node_bus.publish(node_bus.keys.command, Command(stamp_s=time.time(), action="abort", source="console"))
    assert wait_for(rig[0].cancel.is_set)  # set last, once FAILED is latched
    assert machine.state == State.FAILED and machine.reason == "aborted by the operator (from console)"
    # an abort during motion is graceful: the run loop brings the arm to rest on its path, then stops it
    assert rig[0].graceful_stop and not arm.stopped.is_set()
