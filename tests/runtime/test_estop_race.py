"""Every e-stopped run records its ESTOPPED transition, however the run loop and the e-stop interleave.

The race is forced, not hoped for: a hook holds the e-stopping thread at each point where the run loop could
overtake it (right after the arm stopped, and right when `cancel` is set) until the run loop has finished the
run and written its record. Before the fix the first let the run end FAILED by its own stop, the second let the
record close before the transition; the loop repeats both, from a direct call and from the bus, many times.
"""

from __future__ import annotations

import threading
import time
import uuid

import pytest
from runtime_helpers import free_port, wait_for

from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.messaging.bus import Bus
from runtime.messaging.messages import EStop, PlanSummary
from runtime.run.runner import Runtime
from runtime.run.summary import LookRecord, RunSummary, Verification
from runtime.supervision.states import State

pytestmark = pytest.mark.slow

REPEATS = 40


class StreamUntilStopped:
    """Stages that do nothing until execute, which streams the arm's own position until it is stopped."""

    def __init__(self) -> None:
        self.executing = threading.Event()

    def capture(self, ctx) -> None: ...
    def reason(self, ctx) -> None: ...
    def ground(self, ctx) -> None: ...

    def plan(self, ctx) -> PlanSummary:
        return PlanSummary(
            stamp_s=time.time(),
            plan_id=uuid.uuid4().hex[:8],
            run_id=ctx.record.run_id,
            instruction=ctx.instruction,
            duration_s=1.0,
            peak_joint_speed_rad_s=[0.0] * 7,
            samples=2,
            gate_ok=True,
        )

    def recheck(self, ctx) -> LookRecord:
        return LookRecord(capture="look", compared_with=ctx.basis, changes=[], decision="still", reason="", seconds=0.0)

    def execute(self, ctx) -> None:
        arm = ctx.devices.arm
        q = arm.read_state().q
        self.executing.set()
        while not ctx.cancel.is_set():
            arm.servo(q)  # raises ArmStoppedError once the supervisor stopped the arm
            ctx.cancel.wait(0.002)

    def verify(self, ctx) -> Verification:
        return Verification(ok=True, reason="not reached in these tests")

    def stop_motion(self, ctx, reason: str, graceful: bool) -> None: ...


class HookedEvent(threading.Event):
    """`cancel`, with a hook run after set() by any thread but the run loop's."""

    def __init__(self) -> None:
        super().__init__()
        self.hook = None

    def set(self) -> None:
        super().set()
        if self.hook is not None:
            self.hook()


@pytest.fixture(scope="module")
def rig(sim_config_path):
    overrides = {"runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": "estop_race"}}
    profile = load_profile(sim_config_path, overrides)
    with (
        open_devices(profile) as devices,
        Runtime(profile, devices, StreamUntilStopped(), confirm="yes") as rt,
        Bus(profile.runtime.zenoh, profile.runtime.robot_id, "connect") as pendant,
    ):
        assert wait_for(rt.supervisor.deadman_ok, 10)
        yield rt, pendant


def test_the_estopped_transition_is_always_recorded(rig, tmp_path, monkeypatch):
    rt, pendant = rig
    sup = rt.supervisor
    hooked = HookedEvent()
    monkeypatch.setattr(sup, "cancel", hooked)
    real_halt = sup.halt
    window: dict = {}

    def let_the_run_loop_finish() -> None:
        """In the e-stopping thread: wait until the run loop has ended the run and written its record."""
        run_thread = window.get("run_thread")
        if run_thread is None or threading.current_thread() is run_thread:
            return
        window.pop("run_thread")  # once per run
        run_thread.join(10)

    def halt_then_wait() -> None:
        real_halt()
        if window.get("at") == "after halt":
            let_the_run_loop_finish()

    monkeypatch.setattr(sup, "halt", halt_then_wait)
    hooked.hook = lambda: window.get("at") == "at cancel" and let_the_run_loop_finish()

    for i in range(REPEATS):
        at = ("after halt", "at cancel")[i % 2]
        via_bus = i % 4 >= 2
        rt.stages = stages = StreamUntilStopped()
        box: dict = {}
        run_dir = tmp_path / f"run{i}"
        th = threading.Thread(target=lambda d=run_dir, b=box: b.update(result=rt.run("hold still", d)), daemon=True)
        th.start()
        assert stages.executing.wait(10), f"repeat {i}: execution did not start ({rt.machine.reason})"
        window.update(at=at, run_thread=th)
        handled = rt.bus.handled[rt.bus.keys.estop]
        if via_bus:
            pendant.publish(pendant.keys.estop, EStop(stamp_s=time.time(), source="pendant", reason=f"race {i}"))
            estopper_done = lambda n=handled: rt.bus.handled[rt.bus.keys.estop] > n  # noqa: E731
        else:
            estopper = threading.Thread(target=sup.estop, args=(f"race {i}",), daemon=True)
            estopper.start()
            estopper_done = lambda t=estopper: not t.is_alive()  # noqa: E731
        th.join(10)
        assert not th.is_alive(), f"repeat {i}: the run did not end"
        assert wait_for(estopper_done, 10), f"repeat {i}: the e-stop did not return"  # (it latches even late)
        result = box["result"]
        recorded = RunSummary.model_validate_json((run_dir / "summary.json").read_text())
        states = [t.state for t in recorded.transitions]
        what = f"repeat {i} ({at}, {'bus' if via_bus else 'call'}): {result.status} {result.reason!r}, {states}"
        assert result.status == State.ESTOPPED and recorded.status == "ESTOPPED", what
        # held right after the stop, before it read its payload, a bus e-stop is named by its key (the run loop
        # waits ESTOP_REASON_WAIT_S for the payload's reason, then ends the run ESTOPPED without it)
        reason = "e-stop sample on" if via_bus and at == "after halt" else f"race {i}"
        assert states[-1] == "ESTOPPED" and reason in recorded.transitions[-1].reason, what
        assert "FAILED" not in states, what  # the stop's own consequence (a refused set-point) is not a failure
        window.clear()
        rt.reset("test")
