"""Streaming executor on the simulated arm: tracking, refusals, e-stop, abort, faults and a stalled servo call."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from drivers.sim.arm import SimArm
from drivers.sim.world import SimWorld, SteppedClock
from motion.approval import ApprovedTrajectory, GateRefused, approve
from motion.executor import ExecutionRefused, Executor, ExecutorConfig
from motion.timing import GripperAction
from safety.collision import CollisionWorld
from safety.trajectory import JointTrajectory

OFFSET = np.array([0.6, 0.3, 0.0, 0.25, 0.0, -0.2, 0.5])


def _approved(timer, world: CollisionWorld, q0: np.ndarray, *steps) -> ApprovedTrajectory:
    q1 = q0 + OFFSET
    return approve(timer.time(steps or [np.array([q0, q1, q0])]), world, q_current=q0)


def _on_path(q_cmd: np.ndarray, traj: JointTrajectory) -> float:
    """Largest distance of commanded set-points from the trajectory's sample polyline."""
    q = traj.positions
    a, d = q[:-1], np.diff(q, axis=0)
    best = np.full(len(q_cmd), np.inf)
    for k in range(len(d)):
        s = np.clip((q_cmd - a[k]) @ d[k] / max(d[k] @ d[k], 1e-18), 0, 1)
        best = np.minimum(best, np.linalg.norm(q_cmd - (a[k] + s[:, None] * d[k]), axis=1))
    return float(best.max())


def test_executes_the_plan_within_tolerance(sim, timer, limits, free_world):
    world, arm, gripper = sim
    q0 = arm.read_state().q
    q1 = q0 + OFFSET
    approved = _approved(
        timer, free_world, q0, np.array([q0, q1]), GripperAction("close", 0.6, 0.0), np.array([q1, q0])
    )
    ex = Executor(arm, ExecutorConfig(), limits, gripper, clock=SteppedClock(world))
    report = ex.execute(approved)
    traj = approved.trajectory
    assert report.status == "completed", report.reason
    assert report.ticks == len(traj.positions) - 1
    np.testing.assert_allclose(report.q_cmd, traj.positions[1:], atol=1e-12)  # nominal replay: exactly the samples
    assert report.max_step_rad <= 0.04
    # the arm follows: measured position vs the previous set-point, and it ends at the goal
    assert report.max_tracking_error_rad < 0.02
    world.step(0.3)
    np.testing.assert_allclose(arm.read_state().q, q0, atol=5e-3)
    (close,) = report.gripper
    assert close.event.kind == "close" and close.grasped is False and close.width_m < 0.004


def test_refuses_what_the_gate_did_not_pass(sim, timer, limits, free_world):
    world, arm, _ = sim
    q0 = arm.read_state().q
    raw = timer.time([np.array([q0, q0 + OFFSET])])
    ex = Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world))
    with pytest.raises(ExecutionRefused, match="approved by the safety gate"):
        ex.start(raw)
    with pytest.raises(TypeError):
        ApprovedTrajectory(raw, approve(raw, free_world, q0).report, object())
    jumpy = JointTrajectory(raw.joint_names, raw.dt, np.vstack([q0, q0 + 0.2]))
    with pytest.raises(GateRefused, match="refused by the safety gate") as refused:
        approve(jumpy, free_world, q0)
    assert {"step", "velocity"} <= refused.value.report.kinds()
    approved = approve(raw, free_world, q0)
    with pytest.raises(ValueError):
        approved.trajectory.positions[5] += 0.1  # frozen after the check
    with pytest.raises(ExecutionRefused, match="control period"):
        Executor(arm, ExecutorConfig(rate_hz=250), limits, clock=SteppedClock(world)).start(approved)
    arm.servo(q0 + np.array([0.03, 0, 0, 0, 0, 0, 0]))
    world.step(0.2)
    with pytest.raises(ExecutionRefused, match="from the arm at joint 1"):
        ex.start(approved)


def _at_sim_time(world: SimWorld, t: float, action) -> dict:
    """Run `action` once from the physics step that reaches sim time t; records wall time and arm speed."""
    seen: dict = {}

    def hook() -> None:
        if not seen and world.time >= t:
            seen["speed"] = float(np.abs(world.data.qvel[world.arm_dof]).max())
            action()
            seen["wall"] = time.perf_counter()

    world.add_post_step_hook(hook)
    return seen


class _RecordingArm(SimArm):
    """SimArm recording when each accepted set-point was sent (the call's start; a call that was already in
    flight when the e-stop came may return after it, but the stopped arm rejects any call that starts later)."""

    def __init__(self, world: SimWorld) -> None:
        super().__init__(world)
        self.sent: list[float] = []

    def servo(self, q: np.ndarray) -> None:
        t = time.perf_counter()
        super().servo(q)
        self.sent.append(t)


def test_estop_mid_trajectory_stops_within_one_tick(stepped_profile, timer, limits, free_world):
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    arm = _RecordingArm(world)
    arm.connect()
    q0 = arm.read_state().q
    approved = _approved(timer, free_world, q0)
    ex = Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world))
    stop = _at_sim_time(world, 0.4, lambda: ex.estop("test e-stop"))  # mid-move, at speed
    report = ex.execute(approved)
    t_stop, speed_before = stop["wall"], stop["speed"]
    assert report.status == "estopped" and report.reason == "test e-stop"
    assert speed_before > 0.3
    assert all(t < t_stop for t in arm.sent), "a set-point was sent after the e-stop"
    with pytest.raises(Exception, match="stopped"):
        arm.servo(arm.read_state().q)  # the arm holds until clear_fault()
    world.step(0.02)  # two ticks later the controller has braked
    assert np.abs(arm.read_state().qd).max() < 0.1 * speed_before


def test_abort_is_a_jerk_limited_stop_on_the_path(sim, timer, limits, free_world):
    world, arm, _ = sim
    q0 = arm.read_state().q
    approved = _approved(timer, free_world, q0)
    ex = Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world))
    _at_sim_time(world, 0.35, lambda: ex.abort("operator abort"))
    report = ex.execute(approved)
    assert report.status == "aborted" and report.reason == "operator abort"
    assert report.tau_s[-1] < approved.trajectory.duration_s - 0.1  # stopped early
    assert _on_path(report.q_cmd, approved.trajectory) < 1e-9
    v = np.diff(report.q_cmd, axis=0) / 0.01
    a = np.diff(v, axis=0) / 0.01
    assert np.abs(v[-1]).max() < 0.05  # came to rest
    assert np.abs(a).max() <= 1.5 * limits.acceleration.max()  # braking stays near the limits, no slam


def test_controller_fault_stops_at_once(sim_profile_with, timer, limits, free_world):
    profile = sim_profile_with({"sim": {"faults": {"arm_error_at_s": 0.3}}})
    world = SimWorld(profile.sim, profile.camera)
    arm = SimArm(world)
    arm.connect()
    q0 = arm.read_state().q
    report = Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world)).execute(
        _approved(timer, free_world, q0)
    )
    assert report.status == "fault" and "controller error 31" in report.reason
    assert report.times_s[-1] <= 0.3 + 0.011  # the first tick after the fault ends it


def test_step_guard_stops_before_sending_a_big_step(sim, timer, limits, free_world):
    """Defence in depth: with a per-tick limit below the trajectory's steps, the executor stops the arm instead of
    sending the step (the gate normally makes this impossible)."""
    world, arm, _ = sim
    q0 = arm.read_state().q
    report = Executor(arm, ExecutorConfig(max_step_rad=0.002), limits, clock=SteppedClock(world)).execute(
        _approved(timer, free_world, q0)
    )
    assert report.status == "fault" and "exceeds 0.002 rad per tick" in report.reason
    assert report.max_step_rad <= 0.002
    with pytest.raises(ExecutionRefused, match="clear it first"):
        arm._fault = 24  # a latched controller error: nothing is started on top of it
        Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world)).start(_approved(timer, free_world, q0))


class _BlockedArm(SimArm):
    """An arm that reports fresh states but does not move (blocked by something, or a dead servo loop)."""

    def read_state(self):
        state = super().read_state()
        if not hasattr(self, "q_stuck"):
            self.q_stuck = state.q
        return type(state)(state.names, self.q_stuck, state.qd * 0, state.stamp_s, state.fault_code)


def test_tracking_error_stops_an_arm_that_does_not_follow(stepped_profile, timer, limits, free_world):
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    arm = _BlockedArm(world)
    arm.connect()
    q0 = arm.read_state().q
    report = Executor(arm, ExecutorConfig(), limits, clock=SteppedClock(world)).execute(
        _approved(timer, free_world, q0)
    )
    assert report.status == "fault" and "tracking error" in report.reason
    assert 0.05 < report.max_tracking_error_rad < 0.05 + 0.04  # caught on the first tick beyond the bound


class _FrozenStateArm(SimArm):
    """An arm whose state reports stop updating after a while (a dead report stream)."""

    def read_state(self):
        state = super().read_state()
        if state.stamp_s > 0.2:
            return type(state)(state.names, state.q, state.qd, 0.2, state.fault_code)
        return state


def test_stale_state_stops_the_arm(stepped_profile, timer, limits, free_world):
    world = SimWorld(stepped_profile.sim, stepped_profile.camera)
    arm = _FrozenStateArm(world)
    arm.connect()
    q0 = arm.read_state().q
    report = Executor(arm, ExecutorConfig(max_state_age_s=0.05), limits, clock=SteppedClock(world)).execute(
        _approved(timer, free_world, q0)
    )
    assert report.status == "fault" and "stale joint state" in report.reason
    assert report.times_s[-1] < 0.2 + 0.05 + 0.011
    with pytest.raises(Exception, match="stopped"):
        arm.servo(q0)


def test_stalled_servo_call_is_retimed_without_big_steps(sim_profile_with, timer, limits, free_world):
    """Real time: one servo call blocks 0.2 s mid-move; the executor skips the missed ticks and ramps back up
    along the path, never sending a step above the per-tick limit nor leaving the validated path."""
    profile = sim_profile_with({"sim": {"realtime": True, "faults": {"servo_stall_at_s": 0.3, "servo_stall_s": 0.2}}})
    world = SimWorld(profile.sim, profile.camera)
    arm = SimArm(world)
    arm.connect()
    try:
        q0 = arm.read_state().q
        approved = _approved(timer, free_world, q0)
        report = Executor(arm, ExecutorConfig(), limits).execute(approved)
    finally:
        arm.close()
        world.stop()
    assert report.status == "completed", report.reason
    assert report.late_ticks >= 1
    assert report.max_step_rad <= 0.04
    steps = np.abs(np.diff(report.q_cmd, axis=0)).max(axis=1)
    assert steps.max() <= 0.04
    assert _on_path(report.q_cmd, approved.trajectory) < 1e-9
    gaps = np.diff(report.times_s)
    k = int(np.argmax(gaps))
    assert gaps[k] > 0.15  # the stall
    # after the stall the first steps are small (ramping from rest), not the nominal full-speed step
    nominal = np.abs(np.diff(approved.trajectory.positions, axis=0)).max(axis=1)
    assert steps[k + 1] < 0.5 * nominal.max()


def test_estop_from_another_thread_in_real_time(sim_profile_with, timer, limits, free_world):
    profile = sim_profile_with({"sim": {"realtime": True}})
    world = SimWorld(profile.sim, profile.camera)
    arm = _RecordingArm(world)
    arm.connect()
    try:
        q0 = arm.read_state().q
        ex = Executor(arm, ExecutorConfig(), limits)
        ex.start(_approved(timer, free_world, q0))
        threading.Event().wait(0.4)
        ex.estop()
        t_stop = time.perf_counter()
        report = ex.wait(2.0)
    finally:
        arm.close()
        world.stop()
    assert report.status == "estopped"
    assert all(t < t_stop for t in arm.sent)
    assert report.jitter.p99_s < 0.02  # loose: other processes share this machine (bench/motion.py measures it)
