"""From a TCP goal pose to ranked joint-space goals, and the approach/retreat poses around it.

IK runs from the current configuration first, then from random seeds, keeping every distinct collision-free
solution within the joint limits minus the safety margin. Continuous joints are wrapped to the copy nearest the
current configuration (the planner then sees the short way round). Ranking: joint distance from the current
configuration, plus penalties near joint limits and near singularities, so the first solution is the one a
person would expect and the planner's query is short and well-conditioned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from motion.limits import MotionLimits
from safety.collision import CollisionWorld
from safety.ik import IKSettings

LIMIT_ZONE_RAD = 0.3  # closer than this to a joint limit (after the margin) is penalised
SINGULAR_MANIPULABILITY = 0.01  # below this Yoshikawa measure a solution is rejected as near-singular
MANIPULABILITY_REF = 0.05  # below this, a solution is penalised in proportion
DISTINCT_RAD = 0.05  # solutions closer than this (max over joints) are the same solution


class GoalError(RuntimeError):
    """No usable IK solution for the goal pose; the message carries the residual or the reason."""


@dataclass(frozen=True)
class GoalSolution:
    q: np.ndarray
    cost: float
    distance_rad: float  # Euclidean joint distance from the current configuration
    limit_clearance_rad: float  # smallest distance to a joint limit (after the margin)
    manipulability: float


def tool_offset(T_base_tcp: np.ndarray, distance_m: float) -> np.ndarray:
    """The pose moved distance_m along its own -z (the gripper axis points along +z, out of the fingers):
    positive distance backs off, e.g. the approach pose before a grasp or the retreat after it."""
    T = np.array(T_base_tcp, dtype=np.float64, copy=True)
    T[:3, 3] -= distance_m * T[:3, 2]
    return T


def lifted(T_base_tcp: np.ndarray, height_m: float) -> np.ndarray:
    """The pose raised by height_m along the base z axis (a retreat that clears the table)."""
    T = np.array(T_base_tcp, dtype=np.float64, copy=True)
    T[2, 3] += height_m
    return T


def wrap_near(q: np.ndarray, ref: np.ndarray, limits: MotionLimits) -> np.ndarray:
    """Shift each angle by whole turns toward ref wherever the shifted angle stays within the limits."""
    shifted = q + 2 * np.pi * np.round((ref - q) / (2 * np.pi))
    ok = (shifted >= limits.lower) & (shifted <= limits.upper)
    return np.where(ok, shifted, q)


def _score(world: CollisionWorld, limits: MotionLimits, q: np.ndarray, q_current: np.ndarray) -> GoalSolution:
    distance = float(np.linalg.norm(q - q_current))
    clearance = float(np.min(np.minimum(q - limits.lower, limits.upper - q)))
    manip = world.robot.manipulability(q)
    cost = distance + max(0.0, 1 - clearance / LIMIT_ZONE_RAD) + max(0.0, 1 - manip / MANIPULABILITY_REF)
    return GoalSolution(q, cost, distance, clearance, manip)


def ik_goals(
    world: CollisionWorld,
    limits: MotionLimits,
    T_base_tcp: np.ndarray,
    q_current: np.ndarray,
    max_solutions: int = 6,
    attempts: int = 24,
    seed: int = 0,
) -> list[GoalSolution]:
    """Distinct collision-free IK solutions for T_base_tcp, best first. Raises GoalError when there is none."""
    robot = world.robot
    q_current = np.asarray(q_current, dtype=np.float64)
    margin = float(np.max(limits.lower - robot.lower))
    settings = IKSettings(restarts=0, margin_rad=margin)
    rng = np.random.default_rng(seed)

    def acceptable(q: np.ndarray) -> bool:
        return not world.in_collision(q) and robot.manipulability(q) >= SINGULAR_MANIPULABILITY

    found: list[np.ndarray] = []
    best_residual = np.inf
    for k in range(attempts):
        q_seed = q_current if k == 0 else rng.uniform(limits.lower, limits.upper)
        result = robot.ik(T_base_tcp, q_seed, preferred_q=q_current, settings=settings, accept=acceptable)
        if not result.success:
            best_residual = min(best_residual, result.position_error_m)
            continue
        q = wrap_near(result.q, q_current, limits)
        if not acceptable(q):  # wrapping can move a continuous joint into a colliding posture: keep the original
            q = result.q
        if all(np.max(np.abs(q - f)) > DISTINCT_RAD for f in found):
            found.append(q)
        if len(found) >= max_solutions:
            break
    if not found:
        raise GoalError(
            f"no collision-free, non-singular IK solution for the TCP at {np.round(T_base_tcp[:3, 3], 3)} m "
            f"in {attempts} attempts (best position residual {best_residual * 1000:.1f} mm)"
        )
    return sorted((_score(world, limits, q, q_current) for q in found), key=lambda s: s.cost)
