"""Blending: crossing velocities at interior waypoints, and where the gate rejects a blend, dropping it.

Crossing a waypoint at speed bends the segments next to it away from the straight line the planner checked, so
a blend is a proposal: TrajectoryTimer keeps it only where the caller's check (the safety gate) accepts the
sampled result and drops it segment by segment where not.
"""

from __future__ import annotations

import numpy as np
from ruckig import Trajectory

from motion.limits import MotionLimits
from motion.segments import scaled_limits, segment_duration

# Crossing speed cap as a fraction of the joint velocity limit: below 1 so a crossing need not brake at full jerk.
BLEND_SPEED_FRACTION = 0.9
# Crossing speeds tried per joint (fractions of the cap) and coordinate-descent sweeps over all waypoints.
BLEND_LEVELS = (-1.0, -0.6, -0.3, 0.0, 0.3, 0.6, 1.0)
BLEND_SWEEPS = 3


def crossing_velocities(
    waypoints: np.ndarray, rest: list[tuple[Trajectory, float]], limits: MotionLimits
) -> np.ndarray:
    """Crossing velocity per waypoint (ends at rest), chosen to shorten the chain of segments.

    Start: per joint, twice the smaller of the neighbouring segments' mean speeds (rest-to-rest timing) where
    both move the joint the same way, else zero. Then coordinate descent: each joint's crossing speed at each
    waypoint takes the value from BLEND_LEVELS (times its cap) that minimises the two adjacent segments'
    durations. Caps keep every crossing below both segments' scaled velocity limits.
    """
    v = np.zeros_like(waypoints)
    if len(waypoints) < 3:
        return v
    durations = np.array([traj.duration for traj, _ in rest])
    scales = np.array([scale for _, scale in rest])
    mean = np.diff(waypoints, axis=0) / np.maximum(durations, 1e-9)[:, None]
    before, after = mean[:-1], mean[1:]
    same = np.sign(before) * np.sign(after) > 0
    cap = np.minimum(scales[:-1], scales[1:])[:, None] * limits.velocity * BLEND_SPEED_FRACTION
    v[1:-1] = np.where(same, np.sign(after) * np.minimum(2.0 * np.minimum(np.abs(before), np.abs(after)), cap), 0)
    scaled = [scaled_limits(limits, f) for f in scales]

    def cost(i: int) -> float:  # durations of the two segments meeting at waypoint i
        return sum(segment_duration(waypoints[k], v[k], waypoints[k + 1], v[k + 1], scaled[k]) for k in (i - 1, i))

    for _ in range(BLEND_SWEEPS):
        for i in range(1, len(waypoints) - 1):
            for j in range(limits.dof):
                best, best_value = cost(i), v[i, j]
                for level in BLEND_LEVELS:
                    v[i, j] = level * cap[i - 1, j]
                    c = cost(i)
                    if c < best - 1e-9:
                        best, best_value = c, v[i, j]
                v[i, j] = best_value
    return v


def drop_blends_at(
    bad_times, starts, owners: list[tuple[int, int] | None], velocities: list[np.ndarray], dt: float
) -> None:
    """Zero the crossing velocities at both ends of every segment holding a rejected sample (a finite-difference
    sample reaches 3 periods back, so segments ending up to 3 dt before it count too). owners[i] is the (path,
    segment) of piece i starting at starts[i], None for a gripper hold."""
    changed = False
    for t in bad_times:
        for i, owner in enumerate(owners):
            if owner is not None and starts[i] - 1e-9 <= t and starts[i + 1] >= t - 3 * dt:
                path, k = owner
                changed |= bool(np.any(velocities[path][k : k + 2]))
                velocities[path][k : k + 2] = 0.0
    if not changed:  # rejected samples only in rest-to-rest parts: fall back everywhere
        for v in velocities:
            v[:] = 0.0
