"""The manipulation chain (motion + safety, phase by phase) moves a real sim object where the contact poses say.

The contact poses here are built from the simulator's ground truth (a top-down grasp across the block), standing
in for the contact stage so that the chain itself is what is tested: planning, per-phase gate approval and
streaming through the executor."""

from __future__ import annotations

import threading
import types

import numpy as np
import pytest

from drivers.description import load_robot_spec
from motion.executor import Executor, ExecutorConfig
from motion.limits import MotionLimits
from runtime.context import RunContext, StageError
from runtime.devices import open_devices
from runtime.manipulation import ContactPoses, plan_manipulation
from runtime.record import RunRecord
from safety.geometry import Primitive

pytestmark = pytest.mark.slow


def top_down_grasp(T_base_object: np.ndarray, height_m: float) -> np.ndarray:
    """TCP pose pointing down at the object's axis, fingers closing across one of its side-face pairs: of the
    four equivalent choices, the one turning the wrist least from the home posture (TCP x along base x)."""
    z = np.array([0.0, 0.0, -1.0])
    best = None
    for k in range(4):
        angle = k * np.pi / 2
        y = np.cos(angle) * T_base_object[:3, 0] + np.sin(angle) * T_base_object[:3, 1]
        y = y - (y @ z) * z
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        if best is None or x[0] > best[0][0]:
            best = (x, y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([best[0], best[1], z])
    T[:3, 3] = T_base_object[:3, 3] + [0.0, 0.0, height_m]
    return T


@pytest.fixture
def scene(sim_profile_with, tmp_path):
    profile = sim_profile_with({"sim": {"realtime": True}})
    with open_devices(profile) as dev:
        frame = dev.camera.read().with_extrinsics(dev.T_base_camera)
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
    plan = plan_manipulation(ctx, grasp_poses(dev, shift))
    assert plan.phase_names == ("reach", "carry", "leave")
    assert all(p.report.ok for p in plan.phases)  # each phase passed the gate in its own world
    assert max(plan.peak_joint_speed_rad_s) <= ctx.profile.safety.max_joint_velocity_rad_s + 1e-6
    executor = Executor(
        dev.arm,
        ExecutorConfig.from_configs(ctx.profile.robot, ctx.profile.safety),
        MotionLimits.from_config(ctx.profile.safety, load_robot_spec()),
        dev.gripper,
    )
    reports = [executor.execute(p) for p in plan.phases]
    assert [r.status for r in reports] == ["completed"] * 3
    assert reports[0].gripper[0].grasped
    moved = dev.world.object_pose("red_block")[:3, 3] - before
    assert np.linalg.norm(moved - shift) < 0.02, moved


def test_unreachable_goal_is_refused_with_the_reason(scene):
    ctx, dev = scene
    with pytest.raises(StageError, match="IK solution"):
        plan_manipulation(ctx, grasp_poses(dev, np.array([1.5, 0.0, 0.0])))
