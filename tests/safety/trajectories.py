"""Trajectory builders for the safety tests (rest-to-rest minimum-jerk moves at the control rate)."""

from __future__ import annotations

import numpy as np

from safety.trajectory import JointTrajectory

RATE_HZ = 250.0
NAMES = tuple(f"joint{i}" for i in range(1, 8))


def min_jerk(q0: np.ndarray, q1: np.ndarray, duration_s: float, rate_hz: float = RATE_HZ) -> np.ndarray:
    """Samples from q0 (included) to q1 (included) with zero velocity and acceleration at both ends."""
    s = np.linspace(0.0, 1.0, round(duration_s * rate_hz) + 1)
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return np.asarray(q0) + blend[:, None] * (np.asarray(q1) - np.asarray(q0))


def trajectory(positions: np.ndarray, rate_hz: float = RATE_HZ, events=()) -> JointTrajectory:
    return JointTrajectory(NAMES, 1.0 / rate_hz, np.asarray(positions, dtype=np.float64), tuple(events))
