"""The pieces a manipulation is chained from, for one robot, one control period and one scene.

Each piece is motion's (IK goals, OMPL, Cartesian lines, Ruckig) or safety's (the gate); what this adds is one
refusal type naming the piece that failed, with the cause kept.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.config import RobotConfig
from motion.approval import ApprovedTrajectory, GateRefused, approve, gate_check
from motion.cartesian import CartesianPathError, cartesian_path
from motion.config import MotionConfig
from motion.limits import MotionLimits
from motion.planner import Planner, PlanningError
from motion.segments import scaled_limits
from motion.timing import TimingError, TrajectoryTimer
from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.geometry import Primitive
from safety.ik import IKSettings
from safety.robot_model import RobotModel

REACH_TOL_M, REACH_TOL_RAD = 1e-3, 1e-2  # the contact's joints must put the TCP this close to its pose
# where what a plan put down stands in the home gripper's way, it ends at home raised in steps this high, up to this
REST_RAISE_STEP_M, REST_RAISE_MAX_M = 0.02, 0.2


class Approach(Protocol):
    """What a descent reads of a contact (contact.Contact, sweep.SweepContact): its poses and their joints."""

    @property
    def T_pre(self) -> np.ndarray: ...

    @property
    def T_contact(self) -> np.ndarray: ...

    @property
    def q_pre(self) -> np.ndarray: ...

    @property
    def q_contact(self) -> np.ndarray: ...


class ManipulationRefused(RuntimeError):
    """A phase of the manipulation cannot be planned or approved; the message names the piece and why. searched:
    a randomised search found no path (another attempt may); else the refusal is the same on every attempt."""

    def __init__(self, message: str, searched: bool = False) -> None:
        super().__init__(message)
        self.searched = searched


class ManipulationChain:
    """Motion pieces for one robot, one control period and one scene.

    scene: the camera's obstacle points without the target (base frame); target: the target's points, an
    obstacle until the hand reaches it. q_start: where the arm is; the plan starts there and ends at home (rest).
    """

    def __init__(
        self,
        robot: RobotModel,
        *,
        robot_config: RobotConfig,
        safety: SafetyConfig,
        motion: MotionConfig,
        q_start: np.ndarray,
        scene: np.ndarray,
        target: np.ndarray,
    ) -> None:
        self.robot, self.safety, self.motion = robot, safety, motion
        self.limits = scaled_limits(MotionLimits.from_config(safety, robot.spec), motion.speed_scale)
        self.dt = 1.0 / robot_config.control_rate_hz
        self.timer = TrajectoryTimer(
            self.limits, self.dt, robot.joint_names, robot.tcp_positions, safety.max_tcp_speed_m_s
        )
        self.q0 = np.asarray(q_start, dtype=np.float64)
        home = robot_config.home_q_rad
        self.home = np.asarray(home if home is not None else robot.spec.home_q, dtype=np.float64)
        self.scene_points = np.asarray(scene, dtype=np.float64).reshape(-1, 3)
        self.target_points = np.asarray(target, dtype=np.float64).reshape(-1, 3)

    def world(
        self, width_m: float, held: Primitive | None = None, obstacle: np.ndarray | None = None
    ) -> CollisionWorld:
        """The scene without the target; `obstacle` adds points (the target where it stands, before contact)."""
        points = self.scene_points
        if obstacle is not None and len(obstacle):
            points = np.vstack([points, obstacle])
        return CollisionWorld(self.robot, self.safety, points=points, held=held, gripper_width_m=width_m)

    def planner(self, world: CollisionWorld) -> Planner:
        return Planner(world, self.limits, self.motion.planner_config())

    def rest(self, world: CollisionWorld) -> np.ndarray:
        """The posture a plan ends in, valid in `world` (what the plan left where it now is): home; where that
        stands in the home gripper's way (a tall bottle stood up under it), home with the TCP raised straight up
        until clear, at most REST_RAISE_MAX_M; home when none is (the path there is refused with why)."""
        planner = self.planner(world)
        if planner.valid(self.home):
            return self.home
        T_home = self.robot.tcp_pose(self.home)
        settings = IKSettings(restarts=0)
        for lift in np.arange(REST_RAISE_STEP_M, REST_RAISE_MAX_M + 1e-9, REST_RAISE_STEP_M):
            T = T_home.copy()
            T[2, 3] += lift
            r = self.robot.ik(T, self.home, preferred_q=self.home, settings=settings, accept=planner.valid)
            if r.success:
                return r.q
        return self.home

    def checked(self, planner: Planner, q: np.ndarray, T_base_tcp: np.ndarray, what: str) -> np.ndarray:
        """The contact's own joints for the TCP pose T_base_tcp, if they reach it and are valid in this phase's
        world (limits, collision); they are not solved again."""
        q = np.asarray(q, dtype=np.float64)
        T = self.robot.tcp_pose(q)
        miss_m = float(np.linalg.norm(T[:3, 3] - T_base_tcp[:3, 3]))
        turn = float(np.linalg.norm(Rotation.from_matrix(T[:3, :3].T @ T_base_tcp[:3, :3]).as_rotvec()))
        if miss_m > REACH_TOL_M or turn > REACH_TOL_RAD:
            raise ManipulationRefused(
                f"{what}: the contact's joints put the TCP {miss_m * 1000:.1f} mm / {np.degrees(turn):.2f} deg off it"
            )
        if not planner.valid(q):
            raise ManipulationRefused(planner.why_invalid(q, f"{what}: the contact's"))
        return q

    def line(self, planner: Planner, q: np.ndarray, T: np.ndarray, what: str) -> np.ndarray:
        try:
            return cartesian_path(planner, q, T)
        except CartesianPathError as e:
            raise ManipulationRefused(f"{what}: {e}") from e

    def descent(self, before: Planner, touching: Planner, contact: Approach, what: str, pre: str) -> np.ndarray:
        """Joint waypoints of the straight line from the contact's pre-contact pose T_pre down to T_contact, free
        in `touching`'s world; the first are the joints the free path must reach, valid in `before`'s. From the
        contact's own q_pre when that line is free; else the line up from its own q_contact, reversed, if that
        is. The seeded IK down a line keeps the elbow swivel it starts with, and q_pre and q_contact may be on
        two swivels (contact planning solves each pose on its own): near the base, where the elbow folds tight,
        q_pre's may fold link4 onto link2 on the way down while q_contact's, the contact's own clear posture,
        leaves a free line up. Both lines are checked alike (every step and every kept segment)."""
        q_pre = self.checked(before, contact.q_pre, contact.T_pre, pre)
        try:
            return self.line(touching, q_pre, contact.T_contact, what)
        except ManipulationRefused as down:
            try:
                q_contact = self.checked(touching, contact.q_contact, contact.T_contact, f"{what}: the contact")
                up = self.line(touching, q_contact, contact.T_pre, f"{what}, up from the contact's joints")
                self.checked(before, up[-1], contact.T_pre, f"{pre} up from the contact's joints")
            except ManipulationRefused as e:
                raise ManipulationRefused(f"{down}; {e}") from e
            return up[::-1].copy()

    def free(self, planner: Planner, qa: np.ndarray, qb: np.ndarray, what: str) -> np.ndarray:
        try:
            return planner.plan(qa, qb).waypoints
        except PlanningError as e:
            raise ManipulationRefused(f"{what}: {e}", searched=True) from e

    def approved(
        self,
        steps: list,
        world: CollisionWorld,
        q_start: np.ndarray,
        what: str,
        free_move: bool = False,
        tcp_speed_m_s: float | None = None,
    ) -> ApprovedTrajectory:
        """Timed and approved by the gate. A free move (no contact in it) may blend through its waypoints, its
        corners cut where that stays clear and kept only where the gate accepts the bent path; everything else
        rests at each waypoint, on the checked lines. tcp_speed_m_s: a slower TCP than the safety limit (a push,
        a tool pushing small parts)."""
        blend = free_move and self.motion.blend_free_moves
        if blend:  # only paths with corners (a direct move has none, and cutting builds an inflated world)
            steps = [self.planner(world).smooth(s) if isinstance(s, np.ndarray) and len(s) > 2 else s for s in steps]
        timer = self.timer
        if tcp_speed_m_s is not None:
            speed = min(tcp_speed_m_s, self.safety.max_tcp_speed_m_s)
            timer = TrajectoryTimer(self.limits, self.dt, self.robot.joint_names, self.robot.tcp_positions, speed)
        try:
            trajectory = timer.time(steps, blend=blend, check=gate_check(world, q_start) if blend else None)
            return approve(trajectory, world, q_current=q_start)
        except TimingError as e:
            raise ManipulationRefused(f"{what}: timing failed: {e}") from e
        except GateRefused as e:
            raise ManipulationRefused(f"{what}: {e}") from e
