"""The run loop on the sim with a scripted pipeline: the happy path, the record, and every fault ending in the
right state with the arm stopped and the reason recorded."""

from __future__ import annotations

import gc
import json
import threading
import time

import numpy as np
import pytest
from runtime_helpers import free_port, wait_for
from scripted_stages import MOVE_RAD, ScriptedStages

from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, Confirm, Event
from runtime.run.runner import Runtime
from runtime.run.summary import SCHEMA_VERSION, RunSummary
from runtime.supervision.estop import EStopNode
from runtime.supervision.states import State

pytestmark = pytest.mark.slow

UNDER_WAY = 30  # set-points streamed: the motion is under way


def make_profile(sim_config_path, runtime=None, faults=None):
    overrides = {
        "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": "t", **(runtime or {})},
        "sim": {"faults": faults or {}},
    }
    return load_profile(sim_config_path, overrides)


def assert_still(devices, seconds=0.3):
    """Nothing moves: the arm's joints stay put and its velocities are ~0."""
    q0 = devices.arm.read_state().q
    time.sleep(seconds)
    js = devices.arm.read_state()
    assert np.max(np.abs(js.q - q0)) < 2e-3, f"arm still moving: {js.q - q0}"
    assert np.max(np.abs(js.qd)) < 0.05


@pytest.fixture
def session(sim_config_path, tmp_path):
    """Factory: (runtime, devices, stages) on the realtime sim; everything closed at the end."""
    stack = []

    def make(stages=None, confirm="yes", runtime=None, faults=None, prompt=None):
        profile = make_profile(sim_config_path, runtime, faults)
        cm = open_devices(profile)
        devices = cm.__enter__()
        stack.append(cm)
        rt = Runtime(profile, devices, stages or ScriptedStages(), confirm=confirm, prompt=prompt)
        stack.append(rt)
        assert wait_for(rt.supervisor.deadman_ok)
        return rt, devices

    yield make
    for item in reversed(stack):
        item.__exit__(None, None, None)


def run_async(rt, tmp_path, instruction="move the arm"):
    box = {}
    th = threading.Thread(target=lambda: box.update(result=rt.run(instruction, tmp_path / "run")), daemon=True)
    th.start()
    return th, box


def test_happy_path_writes_the_record(session, tmp_path):
    rt, _devices = session()
    result = rt.run("move the arm", tmp_path / "run")
    assert result.ok, result.reason
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["schema_version"] == SCHEMA_VERSION and RunSummary.model_validate(summary) == result.summary
    assert summary["status"] == "DONE" and summary["confirmation"] == {"source": "cli --yes", "approved": True}
    assert set(summary["stage_seconds"]) == {
        "capturing",
        "reasoning",
        "grounding",
        "planning",
        "awaiting_confirm",
        "rechecking",
        "executing",
        "verifying",
    }
    assert [t["state"] for t in summary["transitions"]][-1] == "DONE"
    assert (tmp_path / "run" / "capture.png").stat().st_size > 1000
    assert "DONE" in (tmp_path / "run" / "report.html").read_text()


def test_camera_timeout_fails_capture(session, tmp_path):
    rt, devices = session(faults={"camera_timeout_after_s": 0.0})
    result = rt.run("x", tmp_path / "run")
    assert result.status == State.FAILED and result.reason.startswith("capture: CameraTimeoutError")
    assert_still(devices)


def test_arm_error_mid_trajectory(session, tmp_path):
    stages = ScriptedStages(move_speed_rad_s=0.12)  # a ~5 s move; the controller error comes at sim t = 2.5 s
    rt, devices = session(stages, faults={"arm_error_at_s": 2.5, "arm_error_code": 31})
    result = rt.run("x", tmp_path / "run")
    assert result.status == State.FAILED and "controller error 31" in result.reason
    assert 0 < stages.streamed < stages.planned - 1  # it stopped mid-trajectory
    assert_still(devices)
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["reason"] == result.reason


def test_heartbeat_loss_during_execution_estops(session, tmp_path):
    stages = ScriptedStages(move_speed_rad_s=0.12)
    rt, devices = session(stages)
    th, box = run_async(rt, tmp_path)
    assert stages.executing.wait(10) and wait_for(lambda: stages.streamed >= UNDER_WAY, 5)
    rt.estop_node.paused.set()  # the e-stop node freezes
    th.join(10)
    assert box["result"].status == State.ESTOPPED and "deadman" in box["result"].reason
    assert_still(devices)
    rt.estop_node.paused.clear()
    with pytest.raises(Exception, match="ESTOPPED"):  # latched: no new run before a reset
        rt.machine.advance(State.CAPTURING)


def test_estop_during_execution_from_another_node(session, tmp_path):
    stages = ScriptedStages(move_speed_rad_s=0.12)
    rt, devices = session(stages)
    cfg = rt.profile.runtime
    with Bus(cfg.zenoh, cfg.robot_id, "connect") as pendant_bus:
        pendant = EStopNode(pendant_bus, "pendant", 20).start()
        th, box = run_async(rt, tmp_path)
        assert stages.executing.wait(10) and wait_for(lambda: stages.streamed >= UNDER_WAY, 5)
        streamed = stages.streamed
        pendant.press("operator pressed E-STOP")
        th.join(5)
        pendant.close()
    assert box["result"].status == State.ESTOPPED and "operator pressed E-STOP (from pendant)" in box["result"].reason
    assert stages.streamed - streamed < 10  # streaming ended within a few ticks
    assert_still(devices)
    rt.reset("test")
    assert rt.machine.state == State.IDLE and not rt.arm_halted


def test_stuck_backend_is_cut_off_by_its_budget(session, tmp_path):
    rt, devices = session(ScriptedStages(reason_delay_s=2.0), runtime={"budgets_s": {"reasoning": 0.3}})
    t0 = time.monotonic()
    result = rt.run("x", tmp_path / "run")
    assert time.monotonic() - t0 < 1.5  # the run ended long before the backend returned
    assert result.status == State.FAILED and "REASONING took too long" in result.reason
    assert_still(devices)


def test_backend_timeout_error_fails_with_its_message(session, tmp_path):
    rt, _devices = session(ScriptedStages(reason_error=TimeoutError("image editor: no reply within 60 s")))
    result = rt.run("x", tmp_path / "run")
    assert result.status == State.FAILED
    assert (
        result.reason == "reason: unexpected TimeoutError: image editor: no reply within 60 s (traceback in error.txt)"
    )


def test_implausible_grounding_is_refused(session, tmp_path):
    rt, devices = session(ScriptedStages(ground_error="implausible scale 2.40 (allowed 0.8..1.25)"))
    result = rt.run("x", tmp_path / "run")
    assert result.status == State.FAILED and result.reason == "ground: implausible scale 2.40 (allowed 0.8..1.25)"
    assert_still(devices)


def test_confirm_timeout(session, tmp_path):
    stages = ScriptedStages()
    rt, devices = session(stages, confirm="console", runtime={"budgets_s": {"awaiting_confirm": 0.5}})
    result = rt.run("x", tmp_path / "run")
    assert result.status == State.FAILED and result.reason.startswith("confirm timeout")
    assert stages.streamed == 0
    assert_still(devices)


def test_confirm_for_a_stale_plan_is_rejected(session, tmp_path):
    stages = ScriptedStages()
    rt, _devices = session(stages, confirm="console", runtime={"budgets_s": {"awaiting_confirm": 5.0}})
    cfg = rt.profile.runtime
    with Bus(cfg.zenoh, cfg.robot_id, "connect") as console:
        events = []
        console.subscribe(console.keys.events, Event, lambda k, m: events.append(m.text))
        th, box = run_async(rt, tmp_path)
        assert wait_for(lambda: rt.machine.state == State.AWAITING_CONFIRM, 10)
        plan_id = rt.status.plan_id
        console.publish(console.keys.confirm, Confirm(stamp_s=time.time(), plan_id="old-plan", source="console"))
        assert wait_for(lambda: any("old-plan rejected" in e for e in events))
        assert rt.machine.state == State.AWAITING_CONFIRM and stages.streamed == 0
        console.publish(console.keys.confirm, Confirm(stamp_s=time.time(), plan_id=plan_id, source="console"))
        th.join(20)
    assert box["result"].ok and box["result"].summary.confirmation.source == "console"


def test_abort_during_execution_stops_on_the_path(session, tmp_path):
    stages = ScriptedStages(move_speed_rad_s=0.12)
    rt, devices = session(stages)
    cfg = rt.profile.runtime
    with Bus(cfg.zenoh, cfg.robot_id, "connect") as console:
        th, box = run_async(rt, tmp_path)
        assert stages.executing.wait(10) and wait_for(lambda: stages.streamed >= UNDER_WAY, 5)
        console.publish(console.keys.command, Command(stamp_s=time.time(), action="abort", source="console"))
        th.join(5)
    reason = "aborted by the operator (from console)"
    assert box["result"].status == State.FAILED and box["result"].reason == reason
    # graceful: the run loop asked the stages to come to rest on the path, and the arm was not stopped under them
    assert stages.stops == [(reason, True)]
    ramp = np.array(stages.ramp)
    assert len(ramp) >= 10, f"the arm was stopped {len(ramp)} set-points into the ramp down"
    steps = np.linalg.norm(np.diff(ramp, axis=0), axis=1)
    assert steps[-1] < 0.2 * steps[0]  # slowing down to rest
    direction = MOVE_RAD / np.linalg.norm(MOVE_RAD)  # the scripted path is a straight joint line
    off_path = ramp - ramp[0] - np.outer((ramp - ramp[0]) @ direction, direction)
    assert np.abs(off_path).max() < 1e-9
    assert_still(devices)
    assert rt.arm_halted
    second = rt.run("again", tmp_path / "run2")
    assert second.status == State.FAILED and "press Reset" in second.reason


def test_in_process_estop_refused_on_hardware(sim_config_path):
    profile = make_profile(sim_config_path).model_copy(
        update={"robot": make_profile(sim_config_path).robot.model_copy(update={"kind": "xarm7"})}
    )
    with pytest.raises(ValueError, match="sim only"):
        Runtime(profile, devices=None, stages=ScriptedStages())


@pytest.mark.parametrize("answer", [True, False])
def test_terminal_prompt_sees_the_plan_and_decides(session, tmp_path, answer):
    asked = []
    stages = ScriptedStages()
    # the prompt is under test, not the deadman (tests/runtime/test_supervisor.py): late in a long test process the
    # in-process heartbeat thread has been held off for 0.5 s, which the 0.2 s deadman rightly stops
    runtime = {"deadman_timeout_s": 1.0}
    rt, _ = session(stages, confirm="prompt", runtime=runtime, prompt=lambda plan: asked.append(plan.plan_id) or answer)
    result = rt.run("x", tmp_path / "run")
    assert asked == [result.summary.plan.plan_id]
    if answer:
        assert result.ok and result.summary.confirmation.source == "terminal"
    else:
        assert result.status == State.FAILED and result.reason == f"plan {asked[0]} declined by terminal"
        assert stages.streamed == 0


def test_stalled_driver_call_cannot_hold_the_run(session, tmp_path):
    """A servo call that blocks for 3 s: the executing budget ends the run and the arm is stopped meanwhile."""
    stages = ScriptedStages(move_speed_rad_s=0.12)
    rt, devices = session(
        stages,
        runtime={"budgets_s": {"executing": 1.0}, "deadman_timeout_s": 1.0},  # the budget under test, not the deadman
        faults={"servo_stall_at_s": 0.0, "servo_stall_s": 3.0},
    )
    t0 = time.monotonic()
    result = rt.run("x", tmp_path / "run")
    assert time.monotonic() - t0 < 6.0  # capture .. confirm + 1 s budget, not the 3 s stall on top
    assert result.status == State.FAILED and "EXECUTING took too long" in result.reason
    assert stages.streamed == 0 and rt.supervisor.stop_count >= 1
    assert_still(devices)


def test_an_estop_outlives_its_runtime_until_a_reset(session, tmp_path):
    latch = tmp_path / "estop_latched.json"
    stages = ScriptedStages(move_speed_rad_s=0.12)
    rt, devices = session(stages, runtime={"estop_latch_file": str(latch)})
    th, box = run_async(rt, tmp_path)
    assert stages.executing.wait(10)
    rt.supervisor.estop("operator pressed E-STOP")
    th.join(5)
    assert box["result"].status == State.ESTOPPED and latch.exists()
    assert_still(devices)
    # the next runtime (a new one-shot run) starts from the latch

    later = ScriptedStages()
    rt2, _ = session(later, runtime={"estop_latch_file": str(latch)})
    assert rt2.machine.state == State.ESTOPPED and "operator pressed E-STOP" in rt2.machine.reason
    refused = rt2.run("move the arm", tmp_path / "refused")
    assert refused.status == State.ESTOPPED and "check the cell" in refused.reason and later.streamed == 0
    rt2.reset("test")
    assert not latch.exists() and rt2.machine.state == State.IDLE
    assert rt2.run("move the arm", tmp_path / "after_reset").ok


class FreezeWatchingStages(ScriptedStages):
    """Records how many objects the garbage collector leaves alone in planning and in execution."""

    def plan(self, ctx):
        self.frozen_in_plan = gc.get_freeze_count()
        return super().plan(ctx)

    def execute(self, ctx):
        self.frozen_in_execute = gc.get_freeze_count()
        super().execute(ctx)


def test_execution_runs_with_the_earlier_heap_out_of_the_collectors_walk(session, tmp_path):
    """A full collection over a long-lived process's heap held every thread 0.2-0.6 s (the deadman tripped late in
    the suite): while the arm moves the objects from before are frozen out of it, and handed back afterwards."""
    stages = FreezeWatchingStages()
    rt, _devices = session(stages)
    result = rt.run("move the arm", tmp_path / "run")
    assert result.ok, result.reason
    assert stages.frozen_in_plan == 0
    assert stages.frozen_in_execute > 10_000  # the interpreter's own objects alone are tens of thousands
    assert gc.get_freeze_count() == 0
