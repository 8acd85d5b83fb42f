"""Calibration moves: minimum-jerk joint paths from the measured position, approved by the safety gate and
streamed by the motion executor, with one detour through the home posture when the direct move is refused."""

from __future__ import annotations

import numpy as np

from calibration.poses import PosePlan
from drivers.interfaces import Arm
from motion.approval import ApprovedTrajectory, GateRefused, approve
from motion.clock import Clock, WallClock
from motion.executor import Executor, ExecutorConfig
from motion.interpolate import minimum_jerk_path
from motion.limits import MotionLimits
from safety.collision import CollisionWorld
from safety.trajectory import JointTrajectory


class CalibrationRefused(RuntimeError):
    """The procedure stopped or the result is not good enough; the message says why."""


class GatedMover:
    """Joint moves approved by the safety gate and streamed by the motion executor (tracking error, stale state
    and late calls supervised there). A direct move the gate refuses is tried through the home posture (two
    approved moves); if that is refused too, the move is impossible."""

    def __init__(
        self,
        arm: Arm,
        world: CollisionWorld,
        config: ExecutorConfig,
        limits: MotionLimits,
        max_velocity_rad_s: float,
        clock: Clock | None = None,
    ) -> None:
        self.arm, self.world = arm, world
        self.rate_hz, self.max_velocity = config.rate_hz, max_velocity_rad_s
        self.clock = clock or WallClock()
        self.executor = Executor(arm, config, limits, clock=self.clock)
        self.via = world.robot.home_q

    def _approved(self, q_from: np.ndarray, q_to: np.ndarray) -> tuple[ApprovedTrajectory | None, str]:
        path = minimum_jerk_path(q_from, q_to, self.rate_hz, self.max_velocity)
        trajectory = JointTrajectory(self.arm.joint_names, 1.0 / self.rate_hz, np.vstack([q_from, path]))
        try:
            return approve(trajectory, self.world, q_current=q_from), ""
        except GateRefused as e:
            return None, e.report.reason()

    def route(self, q_from: np.ndarray, q_to: np.ndarray) -> list[ApprovedTrajectory]:
        """Gate-approved trajectories from q_from to q_to; CalibrationRefused with the gate's reason if none."""
        direct, reason = self._approved(q_from, q_to)
        if direct is not None:
            return [direct]
        first, _ = self._approved(q_from, self.via)
        second, _ = self._approved(self.via, q_to) if first is not None else (None, "")
        if first is None or second is None:
            raise CalibrationRefused(f"the safety gate refused the move: {reason}")
        return [first, second]

    def move_to(self, q_to: np.ndarray, settle_s: float = 0.0) -> None:
        """Route from the measured position, execute, wait settle_s; a move that does not complete stops here."""
        for approved in self.route(self.arm.read_state().q, q_to):
            report = self.executor.execute(approved)
            if report.status != "completed":
                raise CalibrationRefused(f"calibration move {report.status}: {report.reason}")
        self.clock.sleep_until(self.clock.now() + settle_s)


def reachable_views(plan: PosePlan, mover: GatedMover, q_start: np.ndarray) -> PosePlan:
    """Drop the views the gate will not let the arm reach from the previous one (checked before anything moves)."""
    kept_T, kept_q, dropped, current = [], [], 0, q_start
    for T, q in zip(plan.T_base_flange, plan.q, strict=True):
        try:
            mover.route(current, q)
        except CalibrationRefused:
            dropped += 1
            continue
        kept_T.append(T)
        kept_q.append(q)
        current = q
    return PosePlan(kept_T, kept_q, plan.rejected + dropped)
