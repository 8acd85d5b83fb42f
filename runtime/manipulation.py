"""From a contact plan to gate-approved trajectories: the pick-and-place or push sequence, phase by phase.

The safety gate checks a trajectory against one collision world, and the world changes during a manipulation
(the object leaves the table and rides in the gripper), so the sequence is cut where it changes and each phase
is approved against its own world:
  grasp:  1. reach: plan to the pre-grasp pose, straight in to the grasp, close, straight up (no held object)
          2. carry: plan to above the place pose with the object attached to the TCP, straight down, open
          3. leave: straight back up with the gripper open, then home (out of the camera's view)
  push:   1. push:  plan to the pre-contact pose, close, straight in, push along the motion, straight back, home
The obstacle world is the camera's point cloud (robot, table and target removed) plus the table and the
profile's workspace and keep-out boxes. The work itself is motion's (IK goals, OMPL, Cartesian lines, Ruckig)
and safety's (the gate); this module only chains it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from motion.approval import ApprovedTrajectory, GateRefused, approve
from motion.cartesian import CartesianPathError, cartesian_path
from motion.goals import GoalError, ik_goals, lifted
from motion.limits import MotionLimits
from motion.planner import Planner, PlanningError
from motion.timing import GripperAction, TimingError, TrajectoryTimer
from runtime.context import RunContext, StageError
from safety.collision import CollisionWorld
from safety.geometry import Primitive
from safety.pointcloud import cloud_from_frame
from safety.robot_model import RobotModel

LIFT_M = 0.10  # straight up after grasping / after releasing
PLACE_CLEARANCE_M = 0.015  # the object is released this far above its goal resting pose (beyond padding)
CLOSE_S, OPEN_S = 1.0, 0.6  # the arm holds still while the gripper moves
HAND_REGION_M = 0.07  # radius about the TCP at capture time whose points belong to the hand


@dataclass(frozen=True)
class ContactPoses:
    """What the contact stage decided, in the base frame (TCP poses)."""

    mode: str  # "grasp" | "push"
    T_pre: np.ndarray  # approach start
    T_contact: np.ndarray  # grasp pose, or where the push starts
    T_goal: np.ndarray  # T_contact moved with the object to its goal (grasp: place pose; push: push end)
    width_m: float  # finger gap to command at contact (grasp: below the object's width)
    held: Primitive | None = None  # the object's geometry in the TCP frame once grasped
    open_width_m: float | None = None  # finger gap for the approach (None: fully open)
    source: str = ""  # who decided (for the record), e.g. "pipeline.contact #1 score 0.82"


@dataclass(frozen=True)
class ManipulationPlan:
    phases: tuple[ApprovedTrajectory, ...]
    phase_names: tuple[str, ...]
    poses: ContactPoses
    tcp_waypoints: dict[str, np.ndarray] = field(default_factory=dict)  # named TCP poses, for the operator's view

    @property
    def duration_s(self) -> float:
        return float(sum(p.trajectory.duration_s for p in self.phases))

    @property
    def samples(self) -> int:
        return int(sum(len(p.trajectory.positions) for p in self.phases))

    @property
    def peak_joint_speed_rad_s(self) -> list[float]:
        peaks = [np.abs(p.trajectory.derivative(1)).max(axis=0) for p in self.phases]
        return np.max(peaks, axis=0).tolist()


class Chain:
    """Motion pieces for one robot, one control period and one scene."""

    def __init__(self, ctx: RunContext) -> None:
        profile, dev = ctx.profile, ctx.devices
        self.robot = RobotModel()
        self.safety = profile.safety
        self.limits = MotionLimits.from_config(profile.safety, self.robot.spec)
        self.dt = 1.0 / profile.robot.control_rate_hz
        self.timer = TrajectoryTimer(
            self.limits, self.dt, self.robot.joint_names, self.robot.tcp_positions, profile.safety.max_tcp_speed_m_s
        )
        self.q0 = dev.arm.read_state().q
        home = profile.robot.home_q_rad
        self.home = np.asarray(home if home is not None else self.robot.spec.home_q, dtype=np.float64)
        points = cloud_from_frame(
            ctx.frame0, self.robot, self.q0, exclude_mask=ctx.goal.mask_init, crop=profile.safety.workspace
        )
        # the open gripper's gap is no robot primitive, so the camera's points of the inner finger faces survive
        # robot removal and would hang in the air where the hand was: drop the grasp region around the TCP
        tcp0 = self.robot.tcp_pose(self.q0)[:3, 3]
        self.points = points[np.linalg.norm(points - tcp0, axis=1) > HAND_REGION_M]

    def world(self, width_m: float, held: Primitive | None = None) -> CollisionWorld:
        return CollisionWorld(self.robot, self.safety, points=self.points, held=held, gripper_width_m=width_m)

    def goal_q(self, world: CollisionWorld, T: np.ndarray, q_near: np.ndarray, what: str) -> np.ndarray:
        try:
            return ik_goals(world, self.limits, T, q_near)[0].q
        except GoalError as e:
            raise StageError(f"{what}: {e}") from None

    def line(self, planner: Planner, q: np.ndarray, T: np.ndarray, what: str) -> np.ndarray:
        try:
            return cartesian_path(planner, q, T)
        except CartesianPathError as e:
            raise StageError(f"{what}: {e}") from None

    def free(self, planner: Planner, qa: np.ndarray, qb: np.ndarray, what: str) -> np.ndarray:
        try:
            return planner.plan(qa, qb).waypoints
        except PlanningError as e:
            raise StageError(f"{what}: {e}") from None

    def approved(self, steps: list, world: CollisionWorld, q_start: np.ndarray, what: str) -> ApprovedTrajectory:
        try:
            trajectory = self.timer.time(steps)
            return approve(trajectory, world, q_current=q_start)
        except TimingError as e:
            raise StageError(f"{what}: timing failed: {e}") from None
        except GateRefused as e:
            raise StageError(f"{what}: {e}") from None


def plan_grasp(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    g = chain.robot.spec.gripper
    open_w = poses.open_width_m or g.max_width_m
    reach_world = chain.world(g.max_width_m)
    planner = Planner(reach_world, chain.limits)
    q_pre = chain.goal_q(reach_world, poses.T_pre, chain.q0, "pre-grasp pose")
    to_pre = chain.free(planner, chain.q0, q_pre, "path to the pre-grasp pose")
    T_lift = lifted(poses.T_contact, LIFT_M)
    approach = chain.line(planner, q_pre, poses.T_contact, "approach to the grasp")
    lift = chain.line(planner, approach[-1], T_lift, "lift after the grasp")
    opening = GripperAction("open", OPEN_S, open_w)
    reach = chain.approved(
        [to_pre, opening, approach, GripperAction("close", CLOSE_S, poses.width_m), lift],
        reach_world,
        chain.q0,
        "reach and grasp",
    )

    carry_world = chain.world(poses.width_m, poses.held)
    carry_planner = Planner(carry_world, chain.limits)
    T_place = lifted(poses.T_goal, PLACE_CLEARANCE_M + chain.safety.padding_m)
    T_above = lifted(T_place, LIFT_M)
    q_above = chain.goal_q(carry_world, T_above, lift[-1], "pose above the place")
    to_above = chain.free(carry_planner, lift[-1], q_above, "carry path")
    down = chain.line(carry_planner, q_above, T_place, "descent to the place pose")
    release = GripperAction("open", OPEN_S, g.max_width_m)
    carry = chain.approved([to_above, down, release], carry_world, lift[-1], "carry")

    leave_world = chain.world(g.max_width_m)
    leave_planner = Planner(leave_world, chain.limits)
    up = chain.line(leave_planner, down[-1], lifted(T_place, LIFT_M), "retreat")
    home = chain.free(leave_planner, up[-1], chain.home, "path home")
    leave = chain.approved([up, home], leave_world, down[-1], "retreat")
    waypoints = {"pre-grasp": poses.T_pre, "grasp": poses.T_contact, "place": T_place}
    return ManipulationPlan((reach, carry, leave), ("reach", "carry", "leave"), poses, waypoints)


def plan_push(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    g = chain.robot.spec.gripper
    world = chain.world(g.min_width_m)
    planner = Planner(world, chain.limits)
    q_pre = chain.goal_q(world, poses.T_pre, chain.q0, "pre-push pose")
    to_pre = chain.free(planner, chain.q0, q_pre, "path to the pre-push pose")
    approach = chain.line(planner, q_pre, poses.T_contact, "approach to the push")
    push = chain.line(planner, approach[-1], poses.T_goal, "push")
    back = chain.line(planner, push[-1], lifted(poses.T_goal, LIFT_M), "retreat after the push")
    home = chain.free(planner, back[-1], chain.home, "path home")
    steps = [to_pre, GripperAction("close", CLOSE_S, g.min_width_m), approach, push, back, home]
    phase = chain.approved(steps, world, chain.q0, "push")
    waypoints = {"pre-push": poses.T_pre, "contact": poses.T_contact, "push end": poses.T_goal}
    return ManipulationPlan((phase,), ("push",), poses, waypoints)


def plan_manipulation(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    if poses.mode == "grasp":
        return plan_grasp(chain, poses)
    if poses.mode == "push":
        return plan_push(chain, poses)
    raise StageError(f"unknown contact mode {poses.mode!r}")
