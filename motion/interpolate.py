"""Minimum-jerk joint-space interpolation: a smooth rest-to-rest move for simple point-to-point motions."""

from __future__ import annotations

import numpy as np

PEAK_VELOCITY_FACTOR = 1.875  # peak of d/ds (10 s^3 - 15 s^4 + 6 s^5) at s = 0.5


def minimum_jerk_path(
    q_from: np.ndarray, q_to: np.ndarray, rate_hz: float, max_velocity: float, min_duration_s: float = 0.5
) -> np.ndarray:
    """Samples (N, dof) at rate_hz, excluding the start, whose peak joint speed stays below max_velocity [rad/s]."""
    q_from, q_to = np.asarray(q_from, float), np.asarray(q_to, float)
    duration = max(min_duration_s, PEAK_VELOCITY_FACTOR * float(np.max(np.abs(q_to - q_from))) / max_velocity)
    n = max(2, int(np.ceil(duration * rate_hz)))
    s = np.linspace(0.0, 1.0, n + 1)[1:]
    blend = 10 * s**3 - 15 * s**4 + 6 * s**5
    return q_from + blend[:, None] * (q_to - q_from)
