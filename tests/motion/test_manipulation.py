"""The manipulation chain (motion + safety, phase by phase) moves a real sim object where the contact plan says.

The contact plan comes from the simulator's ground truth (runtime.sim_truth.oracle), standing in for the contact
stage so that the chain itself is what is tested: the contact's joints checked and planned from, per-phase gate
approval, streaming."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from drivers.description import load_robot_spec
from motion.executor import Executor, ExecutorConfig
from motion.limits import MotionLimits
from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.phases import CLOSE_S, OPEN_S, plan_manipulation
from pipeline.contact.clouds import SceneClouds, scene_clouds
from pipeline.contact.types import ContactPlan
from runtime.devices import Devices, open_devices
from runtime.run.context import StageError
from runtime.sim_truth.oracle import ground_truth_grasp
from safety.robot_model import RobotModel

pytestmark = pytest.mark.slow


@dataclass
class Scene:
    profile: object
    dev: Devices
    robot: RobotModel
    q0: np.ndarray
    clouds: SceneClouds

    def chain(self, profile=None, extra_points: np.ndarray | None = None) -> ManipulationChain:
        profile = profile or self.profile
        points = self.clouds.scene if extra_points is None else np.vstack([self.clouds.scene, extra_points])
        return ManipulationChain(
            self.robot,
            robot_config=profile.robot,
            safety=profile.safety,
            motion=profile.motion,
            q_start=self.q0,
            scene=points,
            target=self.clouds.target,
        )

    def grasp(self, shift_m) -> ContactPlan:
        T_motion = np.eye(4)
        T_motion[:3, 3] = shift_m
        padding = self.profile.safety.padding_m
        return ground_truth_grasp(
            self.dev.world, "red_block", T_motion=T_motion, robot=self.robot, q_start=self.q0, padding_m=padding
        )


@pytest.fixture
def scene(sim_profile_with):
    profile = sim_profile_with({"sim": {"realtime": True}})
    with open_devices(profile) as dev:
        frame = dev.capture()
        robot, q0 = RobotModel(), dev.arm.read_state().q
        mask = dev.camera.object_masks()["red_block"]
        yield Scene(profile, dev, robot, q0, scene_clouds(frame, mask, robot, q0, workspace=profile.safety.workspace))


def test_pick_and_place_moves_the_block(scene):
    dev, profile = scene.dev, scene.profile
    before = dev.world.object_pose("red_block")[:3, 3]
    shift = np.array([0.0, 0.15, 0.0])
    contact = scene.grasp(shift)
    plan = plan_manipulation(scene.chain(), contact)
    assert plan.phase_names == ("approach", "grasp", "carry", "retreat", "home")
    assert all(p.report.ok for p in plan.phases)  # each phase passed the gate in its own world
    # the free paths end at the contact's own joints: not solved again
    np.testing.assert_array_equal(plan.phases[0].trajectory.positions[-1], contact.q_pre)
    np.testing.assert_array_equal(plan.phases[1].trajectory.positions[0], contact.q_pre)
    assert max(plan.peak_joint_speed_rad_s) <= profile.safety.max_joint_velocity_rad_s + 1e-6
    executor = Executor(
        dev.arm,
        ExecutorConfig.from_configs(profile.robot, profile.safety),
        MotionLimits.from_config(profile.safety, load_robot_spec()),
        dev.gripper,
    )
    reports = [executor.execute(p) for p in plan.phases]
    assert [r.status for r in reports] == ["completed"] * 5
    assert [g.grasped for g in reports[1].gripper if g.event.kind == "close"] == [True]
    moved = dev.world.object_pose("red_block")[:3, 3] - before
    assert np.linalg.norm(moved - shift) < 0.02, moved


def test_an_unreachable_goal_is_refused_with_the_reason(scene):
    with pytest.raises(StageError, match=r"goal pose at .* has no IK solution \(position residual"):
        scene.grasp(np.array([1.5, 0.0, 0.0]))


def test_the_contacts_joints_are_checked_in_the_phase_world_not_solved_again(scene):
    contact = scene.grasp(np.array([0.0, 0.15, 0.0]))
    robot = scene.robot
    # an obstacle where the contact's own pre-grasp posture has its elbow: the chain refuses, it does not look for
    # another posture
    elbow = robot.frame_pose(contact.q_pre, "link4")[:3, 3]
    blob = elbow + np.random.default_rng(0).uniform(-0.03, 0.03, (300, 3))
    with pytest.raises(ManipulationRefused, match=r"pre-grasp pose: the contact's configuration is in collision"):
        plan_manipulation(scene.chain(extra_points=blob), contact)
    # joints that do not reach the pose they come with are refused, not corrected
    wrong = replace(contact, q_pre=contact.q_pre + np.array([0.05, 0, 0, 0, 0, 0, 0]))
    with pytest.raises(ManipulationRefused, match=r"pre-grasp pose: the contact's joints put the TCP [\d.]+ mm"):
        plan_manipulation(scene.chain(), wrong)


def test_the_descent_to_the_grasp_checks_the_fingers_at_the_opening_commanded(scene):
    # a wall of points beside the block, along the closing axis: clear of the fingers opened to the block's width
    # plus clearance (0.066 m), in the way of fully open ones (0.085 m); the gate judges what the gripper will do
    contact = replace(scene.grasp(np.array([0.0, 0.15, 0.0])), open_width_m=0.066)
    T = contact.T_contact
    side = -np.sign(T[1, 1]) * T[:3, 1]  # the side away from where the block is carried
    grid = np.stack(np.meshgrid(np.linspace(-0.03, 0.03, 13), np.linspace(0.005, 0.045, 9)), -1).reshape(-1, 2)
    wall = T[:3, 3] + 0.08 * side + grid[:, :1] * T[:3, 0]  # 8 cm out: in the octree cells the gate sees
    wall[:, 2] = grid[:, 1]  # from the table up to just below the block's top
    chain = scene.chain(extra_points=wall)
    q_contact = contact.q_contact
    assert chain.world(0.085).in_collision(q_contact) and not chain.world(0.066).in_collision(q_contact)
    plan = plan_manipulation(chain, contact)
    assert plan.phase_names[1] == "grasp" and plan.phases[1].report.ok


def test_motion_section_scales_the_speed_of_the_whole_plan(scene):
    profile = scene.profile
    contact = scene.grasp(np.array([0.0, 0.15, 0.0]))
    full = plan_manipulation(scene.chain(), contact)
    slow_profile = profile.model_copy(update={"motion": profile.motion.model_copy(update={"speed_scale": 0.5})})
    slow = plan_manipulation(scene.chain(slow_profile), contact)
    assert all(p.report.ok for p in slow.phases)
    assert max(slow.peak_joint_speed_rad_s) <= 0.5 * profile.safety.max_joint_velocity_rad_s + 1e-6
    waits = OPEN_S + CLOSE_S + OPEN_S  # the gripper's open, close and release do not scale
    assert slow.duration_s - waits > 1.6 * (full.duration_s - waits)


def test_free_moves_blend_through_their_waypoints_unless_the_profile_says_no(scene):
    profile = scene.profile
    chain = scene.chain()
    world = chain.world(chain.robot.spec.gripper.max_width_m)
    q0 = chain.q0
    corner = q0 + np.array([0.4, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0])
    path = np.array([q0, corner, corner + np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0])])
    stop = chain.approved([path], world, q0, "stop")
    blended = chain.approved([path], world, q0, "blended", free_move=True)
    assert blended.report.ok and blended.trajectory.duration_s < 0.95 * stop.trajectory.duration_s
    no_blend = profile.model_copy(update={"motion": profile.motion.model_copy(update={"blend_free_moves": False})})
    kept = scene.chain(no_blend).approved([path], world, q0, "kept", free_move=True)
    assert kept.trajectory.duration_s == pytest.approx(stop.trajectory.duration_s)
