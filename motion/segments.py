"""Single Ruckig segments: the time-optimal state-to-state motion within (scaled) joint limits."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Synchronization, Trajectory

from motion.limits import MotionLimits

# Ruckig's profiles may overshoot a limit by ~1e-5 relative; the gate tolerates only rounding, so time a hair
# inside the limits (costs at most 0.1 % of duration).
HEADROOM = 0.999


class TimingError(RuntimeError):
    """Ruckig found no trajectory for a segment, or the input path is unusable."""


def ruckig_segment(q0, v0, q1, v1, limits: MotionLimits) -> Trajectory:
    """Time-optimal state-to-state trajectory (accelerations zero at both ends); rest-to-rest is
    phase-synchronised, so every joint moves on the straight joint-space line."""
    dof = limits.dof
    inp = InputParameter(dof)
    inp.current_position, inp.current_velocity, inp.current_acceleration = q0, v0, np.zeros(dof)
    inp.target_position, inp.target_velocity, inp.target_acceleration = q1, v1, np.zeros(dof)
    inp.max_velocity = limits.velocity * HEADROOM
    inp.max_acceleration = limits.acceleration * HEADROOM
    inp.max_jerk = limits.jerk * HEADROOM
    rest = not (np.any(v0) or np.any(v1))
    inp.synchronization = Synchronization.Phase if rest else Synchronization.Time
    traj = Trajectory(dof)
    result = Ruckig(dof).calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise TimingError(f"Ruckig failed ({result}) from q={np.round(q0, 4)} to q={np.round(q1, 4)}")
    return traj


def segment_duration(q0, v0, q1, v1, limits: MotionLimits) -> float:
    """Duration [s] of ruckig_segment, inf where there is none."""
    try:
        return ruckig_segment(q0, v0, q1, v1, limits).duration
    except (TimingError, RuckigError):
        return np.inf


def scaled_limits(limits: MotionLimits, f: float) -> MotionLimits:
    """Velocity x f, acceleration x f^2, jerk x f^3: the same rest-to-rest motion, 1/f times slower."""
    return replace(
        limits, velocity=limits.velocity * f, acceleration=limits.acceleration * f**2, jerk=limits.jerk * f**3
    )
