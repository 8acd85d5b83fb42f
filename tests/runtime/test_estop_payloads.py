"""Any sample on the estop key stops the arm during EXECUTING and latches ESTOPPED, whatever its payload (the
families a broken, older or newer e-stop node could send); the reason names what was wrong with it, and the arm
is still afterwards."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
from runtime_helpers import free_port, wait_for
from scripted_stages import ScriptedStages

from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.messaging.bus import Bus
from runtime.messaging.messages import EStop, Heartbeat
from runtime.run.runner import Runtime
from runtime.supervision.states import State, StateMachine
from runtime.supervision.supervisor import Supervisor

pytestmark = pytest.mark.slow

UNDER_WAY = 30  # set-points streamed: the motion is under way


def good(**change) -> bytes:
    doc = {"v": 1, "stamp_s": time.time(), "source": "pendant", "reason": "operator pressed E-STOP", **change}
    return json.dumps({k: v for k, v in doc.items() if v is not None}).encode()


FAMILIES = {
    "empty": (lambda: b"", "empty payload"),
    "not json": (lambda: b"STOP STOP STOP", "not JSON"),
    "empty object": (lambda: b"{}", "no schema version v"),
    "invalid utf-8": (lambda: b"\xff\xfe\x00stop", "not UTF-8"),
    "10 MB": (lambda: b"\x00" * (10 * 1024 * 1024), "payload of 10485760 bytes"),
    "json array": (lambda: b'["estop"]', "not a JSON object"),
    "missing stamp_s": (lambda: good(stamp_s=None), "stamp_s: field required"),
    "integer source": (lambda: good(source=42), "source: input should be a valid string"),
    "stamp_s as a word": (lambda: good(stamp_s="now"), "stamp_s: input should be a valid number"),
    "stamp 0": (lambda: good(stamp_s=0), "stamp_s 0 is not a time"),
    "stale stamp": (lambda: good(stamp_s=time.time() - 60), "stale: stamped"),
    "far future": (lambda: good(stamp_s=time.time() + 86400), "in the future"),
    "unknown version": (lambda: good(v=99), "schema version 99 unknown"),
    "nested deeply": (lambda: b"[" * 20000 + b"]" * 20000, "nested too deeply"),
    # a newer e-stop node: fields this runtime does not know are ignored, the stop reads as sent
    "extra field": (lambda: good(severity="high", zone=[1, 2]), "operator pressed E-STOP (from pendant)"),
}


class Arrival:
    """Set-points streamed when an e-stop sample reached the runtime's session (a second subscriber beside the
    supervisor's): the transport takes up to a few hundred milliseconds to carry a 10 MB payload, and the
    runtime's reaction starts when it arrives."""

    def __init__(self) -> None:
        self.stages: ScriptedStages | None = None
        self.streamed: int | None = None
        self.event = threading.Event()

    def expect(self, stages: ScriptedStages) -> None:
        self.stages, self.streamed = stages, None
        self.event.clear()

    def on_sample(self, key: str, payload: bytes) -> None:
        if self.stages is not None and not self.event.is_set():
            self.streamed = self.stages.streamed
            self.event.set()


@pytest.fixture(scope="module")
def rig(sim_config_path):
    overrides = {"runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": "estop_payloads"}}
    profile = load_profile(sim_config_path, overrides)
    with open_devices(profile) as devices, Runtime(profile, devices, ScriptedStages(), confirm="yes") as rt:
        cfg = profile.runtime
        with Bus(cfg.zenoh, cfg.robot_id, "connect") as pendant:
            assert wait_for(rt.supervisor.deadman_ok, 10)
            arrival = Arrival()
            rt.bus.subscribe_bytes(rt.bus.keys.estop, arrival.on_sample)
            yield rt, devices, pendant, arrival


@pytest.fixture
def idle(rig):
    """The rig, reset before and after each test (one test's latch must not fail the next)."""
    rig[0].reset("test")
    yield rig
    if rig[0].machine.state in (State.ESTOPPED, State.FAILED, State.DONE):
        rig[0].reset("test")


def joint_motion_after(devices, seconds: float = 0.3) -> float:
    q0 = devices.arm.read_state().q
    time.sleep(seconds)  # watching the arm for a while is the measurement
    return float(np.max(np.abs(devices.arm.read_state().q - q0)))


@pytest.mark.parametrize("family", list(FAMILIES))
def test_any_estop_payload_stops_the_arm_and_latches(idle, tmp_path, family):
    rt, devices, pendant, arrival = idle
    make, reason = FAMILIES[family]
    stages = rt.stages = ScriptedStages(move_speed_rad_s=0.12)  # a ~5 s move
    arrival.expect(stages)
    box = {}
    th = threading.Thread(target=lambda: box.update(result=rt.run("move the arm", tmp_path / "run")), daemon=True)
    th.start()
    assert stages.executing.wait(15) and wait_for(lambda: stages.streamed >= UNDER_WAY, 5)
    pendant.publish(pendant.keys.estop, make())
    assert arrival.event.wait(5)
    th.join(10)
    result = box["result"]
    assert result.status == State.ESTOPPED, result.reason
    assert reason in result.reason, result.reason
    assert [t.state for t in result.summary.transitions][-1] == "ESTOPPED"
    assert stages.streamed - arrival.streamed < 10  # streaming ended within a few ticks of the sample's arrival
    assert joint_motion_after(devices) < 2e-3
    assert np.max(np.abs(devices.arm.read_state().qd)) < 0.05


def test_a_newer_estop_node_keeps_the_deadman_alive(runtime_cfg):
    """Heartbeats with fields this runtime does not know still count; one of an unknown version does not."""
    with (
        Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "listen") as hub,
        Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "connect") as node,
    ):
        sup = Supervisor(StateMachine(runtime_cfg.budgets_s), hub, None, None, runtime_cfg)
        key = node.keys.heartbeat_of("pendant-v2")

        def beat(**extra) -> None:
            doc = Heartbeat(stamp_s=time.time(), node="pendant-v2", kind="estop", seq=1).model_dump()
            node.publish(key, json.dumps({**doc, **extra}).encode())

        assert wait_for(lambda: beat(battery=0.8, firmware="2.1") or sup.deadman_ok(), 10)
        pattern = f"{hub.keys.heartbeat}/**"
        refused = hub.refused[pattern]
        # beats of an unknown version are refused, so the deadman runs out while they keep coming
        assert wait_for(lambda: beat(v=2) or not sup.deadman_ok(), 3)
        assert hub.refused[pattern] > refused


def test_estop_sample_stops_before_its_payload_is_read(idle, monkeypatch):
    """The arm is stopped first; reading the payload comes after (and even a failure to read it latches)."""
    rt, _devices, pendant, _arrival = idle
    order = []
    import runtime.supervision.supervisor as supervisor_module

    def unreadable(payload: bytes) -> str:
        order.append(("read", rt.supervisor.stop_count))
        raise RuntimeError("a reader bug")

    monkeypatch.setattr(supervisor_module, "estop_reason", unreadable)
    stops = rt.supervisor.stop_count
    pendant.publish(pendant.keys.estop, EStop(stamp_s=time.time(), source="pendant").encode())
    assert wait_for(lambda: rt.machine.state == State.ESTOPPED, 5)
    assert order == [("read", stops + 1)]  # halt() had run when the payload was read
    assert "could not be read (RuntimeError)" in rt.machine.reason
