"""The manipulation chain (motion + safety, phase by phase) moves a real sim object where the contact poses say.

The contact poses come from the simulator's ground truth (runtime.sim_truth.oracle), standing in for the contact
stage so that the chain itself is what is tested: planning, per-phase gate approval, streaming."""

from __future__ import annotations

import threading
import types
from dataclasses import replace

import numpy as np
import pytest

from drivers.description import load_robot_spec
from motion.executor import Executor, ExecutorConfig
from motion.limits import MotionLimits
from motion.manipulation.phases import CLOSE_S, OPEN_S, Chain, ContactPoses, plan_manipulation
from runtime.devices import open_devices
from runtime.run.context import RunContext, StageError
from runtime.run.record import RunRecord
from runtime.sim_truth.oracle import top_down_grasp
from safety.geometry import Primitive

pytestmark = pytest.mark.slow


@pytest.fixture
def scene(sim_profile_with, tmp_path):
    profile = sim_profile_with({"sim": {"realtime": True}})
    with open_devices(profile) as dev:
        frame = dev.capture()
        mask = dev.camera.object_masks()["red_block"]
        ctx = RunContext(
            profile,
            dev,
            "test",
            RunRecord(tmp_path, "t"),
            threading.Event(),
            frame0=frame,
            goal=types.SimpleNamespace(mask_init=mask),
        )
        yield ctx, dev


def grasp_poses(dev, shift_m: np.ndarray) -> ContactPoses:
    T_obj = dev.world.object_pose("red_block")
    T_contact = top_down_grasp(T_obj, 0.03)
    T_pre, T_goal = T_contact.copy(), T_contact.copy()
    T_pre[2, 3] += 0.12
    T_goal[:3, 3] += shift_m
    held = Primitive("held:red_block", load_robot_spec().tcp_link, "box", (0.05, 0.05, 0.05))
    return ContactPoses("grasp", T_pre, T_contact, T_goal, 0.03, held)


def test_pick_and_place_moves_the_block(scene):
    ctx, dev = scene
    before = dev.world.object_pose("red_block")[:3, 3]
    shift = np.array([0.0, 0.15, 0.0])
    plan = plan_manipulation(Chain(ctx), grasp_poses(dev, shift))
    assert plan.phase_names == ("approach", "grasp", "carry", "retreat", "home")
    assert all(p.report.ok for p in plan.phases)  # each phase passed the gate in its own world
    assert max(plan.peak_joint_speed_rad_s) <= ctx.profile.safety.max_joint_velocity_rad_s + 1e-6
    executor = Executor(
        dev.arm,
        ExecutorConfig.from_configs(ctx.profile.robot, ctx.profile.safety),
        MotionLimits.from_config(ctx.profile.safety, load_robot_spec()),
        dev.gripper,
    )
    reports = [executor.execute(p) for p in plan.phases]
    assert [r.status for r in reports] == ["completed"] * 5
    assert [g.grasped for g in reports[1].gripper if g.event.kind == "close"] == [True]
    moved = dev.world.object_pose("red_block")[:3, 3] - before
    assert np.linalg.norm(moved - shift) < 0.02, moved


def test_unreachable_goal_is_refused_with_the_reason(scene):
    ctx, dev = scene
    with pytest.raises(StageError, match="IK solution"):
        plan_manipulation(Chain(ctx), grasp_poses(dev, np.array([1.5, 0.0, 0.0])))


def test_the_descent_to_the_grasp_checks_the_fingers_at_the_opening_commanded(scene):
    # a wall of points beside the block, along the closing axis: clear of the fingers opened to the block's width
    # plus clearance (0.066 m), in the way of fully open ones (0.085 m); the gate judges what the gripper will do
    ctx, dev = scene
    chain = Chain(ctx)
    poses = replace(grasp_poses(dev, np.array([0.0, 0.15, 0.0])), open_width_m=0.066)
    T = poses.T_contact
    side = -np.sign(T[1, 1]) * T[:3, 1]  # the side away from where the block is carried
    grid = np.stack(np.meshgrid(np.linspace(-0.03, 0.03, 13), np.linspace(0.005, 0.045, 9)), -1).reshape(-1, 2)
    wall = T[:3, 3] + 0.08 * side + grid[:, :1] * T[:3, 0]  # 8 cm out: in the octree cells the gate sees
    wall[:, 2] = grid[:, 1]  # from the table up to just below the block's top
    chain.points = np.vstack([chain.points, wall])
    q_contact = chain.robot.ik(T, chain.q0).q
    assert chain.world(0.085).in_collision(q_contact) and not chain.world(0.066).in_collision(q_contact)
    plan = plan_manipulation(chain, poses)
    assert plan.phase_names[1] == "grasp" and plan.phases[1].report.ok


def test_motion_section_scales_the_speed_of_the_whole_plan(scene):
    ctx, dev = scene
    poses = grasp_poses(dev, np.array([0.0, 0.15, 0.0]))
    full = plan_manipulation(Chain(ctx), poses)
    slow_profile = ctx.profile.model_copy(update={"motion": ctx.profile.motion.model_copy(update={"speed_scale": 0.5})})
    slow = plan_manipulation(Chain(replace(ctx, profile=slow_profile)), poses)
    assert all(p.report.ok for p in slow.phases)
    assert max(slow.peak_joint_speed_rad_s) <= 0.5 * ctx.profile.safety.max_joint_velocity_rad_s + 1e-6
    waits = OPEN_S + CLOSE_S + OPEN_S  # the gripper's open, close and release do not scale
    assert slow.duration_s - waits > 1.6 * (full.duration_s - waits)


def test_free_moves_blend_through_their_waypoints_unless_the_profile_says_no(scene):
    ctx, _ = scene
    chain = Chain(ctx)
    world = chain.world(chain.robot.spec.gripper.max_width_m)
    q0 = chain.q0
    corner = q0 + np.array([0.4, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0])
    path = np.array([q0, corner, corner + np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0])])
    stop = chain.approved([path], world, q0, "stop")
    blended = chain.approved([path], world, q0, "blended", free_move=True)
    assert blended.report.ok and blended.trajectory.duration_s < 0.95 * stop.trajectory.duration_s
    no_blend = ctx.profile.model_copy(
        update={"motion": ctx.profile.motion.model_copy(update={"blend_free_moves": False})}
    )
    kept = Chain(replace(ctx, profile=no_blend)).approved([path], world, q0, "kept", free_move=True)
    assert kept.trajectory.duration_s == pytest.approx(stop.trajectory.duration_s)
