"""Kinematic limits used for timing: the safety config's joint limits, scaled by an operator speed factor."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drivers.description import RobotSpec
from safety.config import SafetyConfig


@dataclass(frozen=True)
class MotionLimits:
    """Per-joint bounds [rad, rad/s, rad/s^2, rad/s^3]; `lower`/`upper` already exclude the safety margin."""

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    @classmethod
    def from_config(cls, safety: SafetyConfig, spec: RobotSpec, speed_scale: float = 1.0) -> MotionLimits:
        """Scaling velocity by s, acceleration by s^2 and jerk by s^3 slows a rest-to-rest move by exactly 1/s,
        so the operator's speed factor stretches time without changing the shape of the motion."""
        if not 0.0 < speed_scale <= 1.0:
            raise ValueError(f"speed_scale must be in (0, 1], got {speed_scale}")
        n = len(spec.joint_names)
        vel = np.minimum(safety.max_joint_velocity_rad_s, spec.velocity_limits)
        return cls(
            velocity=vel * speed_scale,
            acceleration=np.full(n, safety.max_joint_acceleration_rad_s2 * speed_scale**2),
            jerk=np.full(n, safety.max_joint_jerk_rad_s3 * speed_scale**3),
            lower=spec.lower + safety.joint_margin_rad,
            upper=spec.upper - safety.joint_margin_rad,
        )

    @property
    def dof(self) -> int:
        return len(self.velocity)

    def check_positions(self, q: np.ndarray, what: str) -> None:
        """Raise ValueError naming the first sample and joint outside [lower, upper]."""
        q = np.atleast_2d(q)
        bad = np.argwhere((q < self.lower) | (q > self.upper))
        if bad.size:
            k, j = bad[0]
            raise ValueError(
                f"{what} {k}: joint {j + 1} = {q[k, j]:.4f} rad outside [{self.lower[j]:.4f}, {self.upper[j]:.4f}]"
            )
