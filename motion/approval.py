"""The only way to a streamable trajectory: the safety gate's approval.

`approve` runs safety.gate.validate on a frozen copy of the trajectory and returns an ApprovedTrajectory only
when the gate finds no violation; the executor accepts nothing else, so no set-point reaches a driver unchecked
and nobody can edit a trajectory after it was checked.
"""

from __future__ import annotations

import numpy as np

from safety.collision import CollisionWorld
from safety.gate import GateReport, validate
from safety.trajectory import JointTrajectory

_TOKEN = object()


class GateRefused(RuntimeError):
    """The gate found violations; `report` lists them all."""

    def __init__(self, report: GateReport) -> None:
        super().__init__(f"trajectory refused by the safety gate: {report.reason()}")
        self.report = report


class ApprovedTrajectory:
    """A read-only trajectory with the gate report that passed it. Construct with approve() only."""

    __slots__ = ("report", "trajectory")

    def __init__(self, trajectory: JointTrajectory, report: GateReport, token: object) -> None:
        if token is not _TOKEN or not report.ok:
            raise TypeError("ApprovedTrajectory is created by motion.approval.approve() after the gate passes")
        self.trajectory = trajectory
        self.report = report


def frozen(trajectory: JointTrajectory) -> JointTrajectory:
    """A copy whose positions cannot be written."""
    q = np.array(trajectory.positions, dtype=np.float64, copy=True)
    q.flags.writeable = False
    return JointTrajectory(trajectory.joint_names, trajectory.dt, q, trajectory.gripper_events)


def approve(
    trajectory: JointTrajectory, world: CollisionWorld, q_current: np.ndarray | None = None
) -> ApprovedTrajectory:
    """Gate-check the trajectory (from the arm's current position q_current, when given); GateRefused if not ok."""
    checked = frozen(trajectory)
    report = validate(checked, world, q_current=q_current)
    if not report.ok:
        raise GateRefused(report)
    return ApprovedTrajectory(checked, report, _TOKEN)


def gate_check(world: CollisionWorld, q_current: np.ndarray | None = None):
    """The gate as a timing check: the times of every violation (blended timing keeps what passes)."""

    def check(trajectory: JointTrajectory) -> list[float]:
        return [v.time_s for v in validate(trajectory, world, q_current=q_current).violations]

    return check
