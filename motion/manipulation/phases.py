"""From a contact plan to gate-approved trajectories: the pick-and-place or push sequence, phase by phase.

The safety gate checks a trajectory against one collision world, and the world changes during a manipulation
(the object is an obstacle until the hand reaches it, then rides in the gripper, then stands somewhere new), so
the sequence is cut where it changes and each phase is approved against its own world. The arm rests at every
cut anyway (rest-to-rest timing at waypoints), so the cuts cost no time.
  grasp:  approach (free path to the pre-grasp pose; the object is an obstacle) -> grasp (straight in, close,
          straight up) -> carry (object attached to the TCP: free path above the place pose, straight down, open)
          -> retreat (straight up) -> home (the placed object is an obstacle)
  push:   approach (free path, close the fingers) -> push (straight in, push along the motion, back up) -> home
  hinge:  as push, the push following the via poses along the hinged part's arc (a Cartesian line between each
          two), ending just off the turned part, whence straight up is away from it
The obstacle world is the camera's point cloud (robot, table and target removed) plus the table and the
profile's workspace and keep-out boxes. The work itself is motion's (IK goals, OMPL, Cartesian lines, Ruckig)
and safety's (the gate); this module only chains it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from motion.approval import ApprovedTrajectory, GateRefused, approve, gate_check
from motion.cartesian import CartesianPathError, cartesian_path
from motion.goals import GoalError, ik_goals, lifted
from motion.limits import MotionLimits
from motion.planner import Planner, PlanningError
from motion.segments import scaled_limits
from motion.timing import GripperAction, TimingError, TrajectoryTimer
from runtime.run.context import RunContext, StageError
from safety.collision import CollisionWorld
from safety.geometry import Primitive, transform_points
from safety.pointcloud import cloud_from_frame
from safety.robot_model import RobotModel

LIFT_M = 0.10  # straight up after grasping / after releasing
PLACE_CLEARANCE_M = 0.015  # the object is released this far above its goal resting pose (beyond padding)
CLOSE_S, OPEN_S = 1.0, 0.6  # the arm holds still while the gripper moves
TARGET_MARGIN_M = 0.015  # cloud points this close to the target's own points are the target's
HAND_REGION_M = 0.07  # radius about the TCP at capture time whose points belong to the hand


@dataclass(frozen=True)
class ContactPoses:
    """What the contact stage decided, in the base frame (TCP poses)."""

    mode: str  # "grasp" | "push" | "hinge"
    T_pre: np.ndarray  # approach start
    T_contact: np.ndarray  # grasp pose, or where the push starts
    T_goal: np.ndarray  # T_contact moved with the object to its goal (grasp: place pose; push: push end)
    width_m: float  # finger gap to command at contact (grasp: below the object's width)
    held: Primitive | None = None  # the object's geometry in the TCP frame once grasped
    open_width_m: float | None = None  # finger gap for the approach (None: fully open)
    source: str = ""  # who decided (for the record), e.g. "pipeline.contact #1 score 0.82"
    via: tuple[np.ndarray, ...] = ()  # TCP poses the push passes between contact and goal (hinge: the arc)
    T_motion: np.ndarray | None = None  # the object's motion (None: T_goal T_contact^-1, the TCP rides it rigidly)

    @property
    def object_motion(self) -> np.ndarray:
        """x_goal = T x_init of the object (base frame); a hinge push's TCP does not turn with the part."""
        return self.T_motion if self.T_motion is not None else self.T_goal @ np.linalg.inv(self.T_contact)


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
        self.motion = profile.motion
        self.limits = scaled_limits(MotionLimits.from_config(profile.safety, self.robot.spec), self.motion.speed_scale)
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
        points = points[np.linalg.norm(points - tcp0, axis=1) > HAND_REGION_M]
        # depth smears the target's edges beyond its mask: drop what lies next to the target's own points too,
        # or the carry would collide with a ghost of the object where it used to stand
        frame = ctx.frame0
        valid = ctx.goal.mask_init & np.isfinite(frame.depth)
        self.target_points = transform_points(
            frame.T_base_camera, frame.intrinsics.unproject_depth_image(frame.depth)[valid]
        )
        if len(self.target_points) and len(points):
            near, _ = cKDTree(self.target_points).query(points, distance_upper_bound=TARGET_MARGIN_M)
            points = points[~np.isfinite(near)]
        self.points = points

    def world(
        self, width_m: float, held: Primitive | None = None, obstacle: np.ndarray | None = None
    ) -> CollisionWorld:
        """The scene without the target; `obstacle` adds points (the target where it stands, before contact)."""
        points = self.points if obstacle is None or not len(obstacle) else np.vstack([self.points, obstacle])
        return CollisionWorld(self.robot, self.safety, points=points, held=held, gripper_width_m=width_m)

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

    def planner(self, world: CollisionWorld) -> Planner:
        return Planner(world, self.limits, self.motion.planner_config())

    def free(self, planner: Planner, qa: np.ndarray, qb: np.ndarray, what: str) -> np.ndarray:
        try:
            return planner.plan(qa, qb).waypoints
        except PlanningError as e:
            raise StageError(f"{what}: {e}") from None

    def approved(
        self, steps: list, world: CollisionWorld, q_start: np.ndarray, what: str, free_move: bool = False
    ) -> ApprovedTrajectory:
        """Timed and approved by the gate. A free move (no contact in it) may blend through its waypoints, its
        corners cut where that stays clear and kept only where the gate accepts the bent path; everything else
        rests at each waypoint, on the checked lines."""
        blend = free_move and self.motion.blend_free_moves
        if blend:  # only paths with corners (a direct move has none, and cutting builds an inflated world)
            steps = [self.planner(world).smooth(s) if isinstance(s, np.ndarray) and len(s) > 2 else s for s in steps]
        try:
            trajectory = self.timer.time(steps, blend=blend, check=gate_check(world, q_start) if blend else None)
            return approve(trajectory, world, q_current=q_start)
        except TimingError as e:
            raise StageError(f"{what}: timing failed: {e}") from None
        except GateRefused as e:
            raise StageError(f"{what}: {e}") from None


def plan_grasp(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    g = chain.robot.spec.gripper
    open_w = poses.open_width_m or g.max_width_m
    before = chain.world(g.max_width_m, obstacle=chain.target_points)  # the object is an obstacle until touched
    q_pre = chain.goal_q(before, poses.T_pre, chain.q0, "pre-grasp pose")
    to_pre = chain.free(chain.planner(before), chain.q0, q_pre, "path to the pre-grasp pose")
    approach = chain.approved(
        [to_pre, GripperAction("open", OPEN_S, open_w)], before, chain.q0, "approach", free_move=True
    )

    touching = chain.world(open_w)  # the approach ended opening the fingers to open_w: no wider down to the grasp
    planner = chain.planner(touching)
    down = chain.line(planner, q_pre, poses.T_contact, "approach to the grasp")
    lift = chain.line(planner, down[-1], lifted(poses.T_contact, LIFT_M), "lift after the grasp")
    grasp = chain.approved([down, GripperAction("close", CLOSE_S, poses.width_m), lift], touching, q_pre, "grasp")

    carry_world = chain.world(poses.width_m, held=poses.held)
    carry_planner = chain.planner(carry_world)
    T_place = lifted(poses.T_goal, PLACE_CLEARANCE_M + chain.safety.padding_m)
    q_above = chain.goal_q(carry_world, lifted(T_place, LIFT_M), lift[-1], "pose above the place")
    to_above = chain.free(carry_planner, lift[-1], q_above, "carry path")
    place = chain.line(carry_planner, q_above, T_place, "descent to the place pose")
    release = GripperAction("open", OPEN_S, g.max_width_m)
    carry = chain.approved([to_above, place, release], carry_world, lift[-1], "carry")

    released = chain.world(g.max_width_m)
    up = chain.line(chain.planner(released), place[-1], lifted(T_place, LIFT_M), "retreat")
    retreat = chain.approved([up], released, place[-1], "retreat")
    home = _home(chain, poses, g.max_width_m, up[-1])
    phases = (approach, grasp, carry, retreat, home)
    waypoints = {"pre-grasp": poses.T_pre, "grasp": poses.T_contact, "place": T_place}
    return ManipulationPlan(phases, ("approach", "grasp", "carry", "retreat", "home"), poses, waypoints)


def plan_push(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    g = chain.robot.spec.gripper
    before = chain.world(g.max_width_m, obstacle=chain.target_points)
    q_pre = chain.goal_q(before, poses.T_pre, chain.q0, "pre-push pose")
    to_pre = chain.free(chain.planner(before), chain.q0, q_pre, "path to the pre-push pose")
    approach = chain.approved(
        [to_pre, GripperAction("close", CLOSE_S, g.min_width_m)], before, chain.q0, "approach", free_move=True
    )

    touching = chain.world(g.min_width_m)
    planner = chain.planner(touching)
    path = [chain.line(planner, q_pre, poses.T_contact, "approach to the push")]
    for k, T in enumerate((*poses.via, poses.T_goal), start=1):
        what = f"push (arc pose {k} of {len(poses.via) + 1})" if poses.via else "push"
        path.append(chain.line(planner, path[-1][-1], T, what))
    back = chain.line(planner, path[-1][-1], lifted(poses.T_goal, LIFT_M), "retreat after the push")
    pushing = chain.approved([*path, back], touching, q_pre, "push")
    home = _home(chain, poses, g.min_width_m, back[-1])
    arc = {f"arc {k}": T for k, T in enumerate(poses.via, start=1)}
    waypoints = {"pre-push": poses.T_pre, "contact": poses.T_contact, **arc, "push end": poses.T_goal}
    return ManipulationPlan((approach, pushing, home), ("approach", "push", "home"), poses, waypoints)


def _home(chain: Chain, poses: ContactPoses, width_m: float, q_start: np.ndarray) -> ApprovedTrajectory:
    """Back to the home posture, with the object where it now is as an obstacle."""
    world = chain.world(width_m, obstacle=transform_points(poses.object_motion, chain.target_points))
    path = chain.free(chain.planner(world), q_start, chain.home, "path home")
    return chain.approved([path], world, q_start, "home", free_move=True)


def plan_manipulation(chain: Chain, poses: ContactPoses) -> ManipulationPlan:
    if poses.mode == "grasp":
        return plan_grasp(chain, poses)
    if poses.mode in ("push", "hinge"):
        return plan_push(chain, poses)
    raise StageError(f"unknown contact mode {poses.mode!r}")
