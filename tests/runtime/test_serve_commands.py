"""A serving runtime (`goalvla run --serve`) takes at most one operator request at a time: a Run during a run is
refused with an event saying why, never queued, so it cannot start a run by itself after an Abort; a flood of
requests costs nothing; a command of an unknown version or with a bad stamp is not carried out."""

from __future__ import annotations

import json
import threading
import time

import pytest
from runtime_helpers import free_port, wait_for
from scripted_stages import ScriptedStages

from runtime.commands.serve import serve
from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, Event
from runtime.run.runner import Runtime
from runtime.supervision.command_slot import CommandSlot
from runtime.supervision.states import State

FLOOD = 2000


def command(action: str, instruction: str = "") -> Command:
    return Command(stamp_s=time.time(), action=action, instruction=instruction, source="console")


def test_the_slot_holds_one_request_and_says_why_it_refuses():
    slot = CommandSlot()
    assert slot.offer(command("run", "a"), State.IDLE) is None
    assert slot.offer(command("run", "b"), State.IDLE) == "run refused: the previous request is still being carried out"
    assert slot.take().instruction == "a" and slot.take() is None
    assert "still being carried out" in slot.offer(command("reset"), State.DONE)  # taken, not done yet
    slot.done()
    assert slot.offer(command("run", "c"), State.EXECUTING) == (
        "run refused: a run is in progress (EXECUTING); abort it first"
    )
    assert slot.offer(command("run", "c"), State.ESTOPPED) == "run refused: ESTOPPED; check the cell, then press Reset"
    assert slot.offer(command("run", " "), State.IDLE) == "run refused: no instruction"
    assert slot.offer(command("reset"), State.ESTOPPED) is None


@pytest.fixture
def served(sim_config_path, tmp_path):
    runtime = {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": "serve_test", "runs_dir": tmp_path}
    profile = load_profile(sim_config_path, {"runtime": runtime})
    stop = threading.Event()
    with open_devices(profile) as devices, Runtime(profile, devices, ScriptedStages(), confirm="console") as rt:
        th = threading.Thread(target=serve, args=(rt, stop), daemon=True)
        th.start()
        with Bus(profile.runtime.zenoh, profile.runtime.robot_id, "connect") as console:
            events: list[str] = []
            console.subscribe(console.keys.events, Event, lambda k, m: events.append(m.text))
            assert wait_for(rt.supervisor.deadman_ok, 10)
            yield rt, console, events, tmp_path
        stop.set()
        th.join(5)


def run_folders(runs_dir) -> list:
    return sorted(p for p in runs_dir.iterdir() if p.is_dir())


@pytest.mark.slow
def test_runs_sent_during_a_run_are_refused_and_never_start_after_an_abort(served):
    rt, console, events, runs_dir = served
    console.publish(console.keys.command, command("run", "move the arm"))
    assert wait_for(lambda: rt.machine.state == State.AWAITING_CONFIRM, 20)
    handled = rt.bus.handled[rt.bus.keys.command]
    for _ in range(FLOOD):
        console.publish(console.keys.command, command("run", "move it again"))
    assert wait_for(lambda: rt.bus.handled[rt.bus.keys.command] >= handled + FLOOD, 30)
    assert rt.supervisor.commands.take() is None  # nothing waits
    refusals = [e for e in events if e.startswith("run refused: a run is in progress (AWAITING_CONFIRM)")]
    assert refusals and len(events) < 100  # said, and throttled: a flood of requests is not a flood of events
    console.publish(console.keys.command, command("abort"))
    assert wait_for(lambda: rt.machine.state == State.FAILED, 10)
    assert "aborted by the operator" in rt.machine.reason
    console.publish(console.keys.command, command("reset"))  # carried out next: nothing else was waiting
    assert wait_for(lambda: rt.machine.state == State.IDLE, 10)
    assert len(run_folders(runs_dir)) == 1
    assert rt.machine.state == State.IDLE


@pytest.mark.slow
def test_commands_of_unknown_versions_or_bad_stamps_are_not_carried_out(served):
    rt, console, _events, runs_dir = served
    pattern = rt.bus.keys.command
    good = command("run", "move the arm").model_dump()
    bad = [{**good, "v": 99}, {**good, "stamp_s": 0}, {**good, "stamp_s": time.time() - 3600}, {**good, "x": 1}]
    for doc in bad:
        console.publish(console.keys.command, json.dumps(doc).encode())
    assert wait_for(lambda: rt.bus.refused[pattern] == len(bad), 10)
    assert rt.machine.state == State.IDLE and run_folders(runs_dir) == []
    assert rt.supervisor.commands.take() is None
