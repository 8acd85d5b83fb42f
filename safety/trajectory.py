"""The trajectory that the gate checks and the executor streams: joint positions at a fixed period.

Positions are what reaches the arm in servo mode, so velocity, acceleration and jerk are derived from them by
finite differences (what the arm will actually be asked to do), not taken from the planner's own claims.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np


@dataclass(frozen=True)
class GripperEvent:
    """A gripper action at time_s [s] from the trajectory start; `wait` holds the arm for duration_s."""

    time_s: float
    kind: Literal["open", "close", "wait"]
    width_m: float = 0.0
    duration_s: float = 0.0


@dataclass(frozen=True)
class JointTrajectory:
    joint_names: tuple[str, ...]
    dt: float  # sample period [s]
    positions: np.ndarray  # (N, dof) [rad]; sample k is commanded at time k * dt
    gripper_events: tuple[GripperEvent, ...] = field(default=())

    def __post_init__(self) -> None:
        q = np.asarray(self.positions, dtype=np.float64)
        if q.ndim != 2 or q.shape[1] != len(self.joint_names) or q.shape[0] < 1:
            raise ValueError(f"positions must be (N, {len(self.joint_names)}), got {q.shape}")
        if not np.isfinite(self.dt) or self.dt <= 0:
            raise ValueError(f"dt must be a positive number of seconds, got {self.dt}")
        if not np.all(np.isfinite(q)):
            raise ValueError("positions contain NaN or inf")
        object.__setattr__(self, "positions", q)

    @property
    def duration_s(self) -> float:
        return (len(self.positions) - 1) * self.dt

    @property
    def times(self) -> np.ndarray:
        return np.arange(len(self.positions)) * self.dt

    def derivative(self, order: int) -> np.ndarray:
        """Backward finite difference of the given order (1 velocity, 2 acceleration, 3 jerk), at rest before
        the first sample; row k is the value over the step that ends at sample k."""
        q = np.vstack([np.repeat(self.positions[:1], order, axis=0), self.positions])
        d = q
        for _ in range(order):
            d = np.diff(d, axis=0) / self.dt
        return d
