"""Vectorised limit checks on sampled joint positions: position (with margin), velocity, acceleration, jerk,
per-tick step and TCP speed.

Derivatives are finite differences of the positions, because positions are what the arm is sent. The arm is at
rest before the first sample and holds the last sample afterwards, so the start-up and the final stop are
checked too: a trajectory that ends at speed implies an instant stop, and the gate says so. A difference that
overflows (an absurd jump) is inf or NaN and counts as exceeding every limit. With a ListingBudget, only the
first violations of each kind are built and the rest counted.
"""

from __future__ import annotations

import numpy as np

from safety.config import SafetyConfig
from safety.violations import ListingBudget, Violation, ViolationKind

_REL_TOL = 1e-9  # numbers equal to a limit up to rounding pass
_UNITS = {"velocity": "rad/s", "acceleration": "rad/s^2", "jerk": "rad/s^3"}


def exceeds(value: np.ndarray, limit) -> np.ndarray:
    """value above limit beyond rounding; NaN (an overflowed difference) exceeds too."""
    return ~(value <= np.asarray(limit) * (1 + _REL_TOL) + 1e-12)


def _rad(x: float) -> str:
    """Four decimals, or four digits for an absurd value (1e300 rad would print 300 of them)."""
    return f"{x:.4f}" if abs(x) < 1e6 else f"{x:.4g}"


def _listed(hits: tuple[np.ndarray, ...], kind: ViolationKind, budget: ListingBudget | None):
    """The hits (index arrays) to build violations for: all, or the budget's share of them."""
    n = len(hits[0]) if budget is None else budget.take(kind, len(hits[0]))
    return zip(*(h[:n] for h in hits), strict=True)


def joint_limit_violations(
    positions: np.ndarray,
    times: np.ndarray,
    names,
    lower: np.ndarray,
    upper: np.ndarray,
    margin_rad: float,
    budget: ListingBudget | None = None,
) -> list[Violation]:
    """Every (sample, joint) closer than margin_rad to, or beyond, a position limit."""
    lo, hi = lower + margin_rad, upper - margin_rad
    out = []
    hits = np.nonzero((positions < lo - 1e-12) | (positions > hi + 1e-12))
    for k, j in _listed(hits, "joint_limit", budget):
        q = float(positions[k, j])
        bound, side = (float(lo[j]), "below") if q < lo[j] else (float(hi[j]), "above")
        out.append(
            Violation(
                float(times[k]),
                "joint_limit",
                (names[j],),
                q,
                bound,
                f"{names[j]} at {_rad(q)} rad is {side} its limit {bound:.4f} rad (margin {margin_rad} rad included)",
            )
        )
    return out


def rest_padded_derivative(positions: np.ndarray, dt: float, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Backward differences of the given order over [rest before] + samples + [hold after]. Returns (values,
    sample index at which each difference ends); indices >= N lie after the last sample."""
    pad = 3
    p = np.vstack([np.repeat(positions[:1], pad, axis=0), positions, np.repeat(positions[-1:], pad, axis=0)])
    d = p
    for _ in range(order):
        d = np.diff(d, axis=0) / dt
    ends = np.arange(len(d)) + order - pad
    return d, ends


def derivative_violations(
    positions: np.ndarray, dt: float, names, config: SafetyConfig, velocity_limits, budget: ListingBudget | None = None
) -> list:
    """Velocity (per joint: the stricter of profile and description), acceleration and jerk violations."""
    bounds: dict[ViolationKind, np.ndarray] = {
        "velocity": np.minimum(config.max_joint_velocity_rad_s, velocity_limits),
        "acceleration": np.full(len(names), config.max_joint_acceleration_rad_s2),
        "jerk": np.full(len(names), config.max_joint_jerk_rad_s3),
    }
    n = len(positions)
    out = []
    for order, (kind, limit) in enumerate(bounds.items(), start=1):
        d, ends = rest_padded_derivative(positions, dt, order)
        for i, j in _listed(np.nonzero(exceeds(np.abs(d), limit)), kind, budget):
            when = "" if ends[i] < n else " (stopping after the last sample)"
            out.append(
                Violation(
                    float(ends[i] * dt),
                    kind,
                    (names[j],),
                    float(d[i, j]),
                    float(limit[j]),
                    f"{names[j]} {kind} {d[i, j]:.4g} {_UNITS[kind]} exceeds {limit[j]:.4g}{when}",
                )
            )
    return out


def step_violations(
    positions: np.ndarray,
    times: np.ndarray,
    names,
    max_step_rad: float,
    q_start=None,
    budget: ListingBudget | None = None,
) -> list:
    """Set-point changes per control tick larger than max_step_rad; q_start (the arm's current position), when
    given, is the set-point before the first sample."""
    prev = positions[:1] if q_start is None else np.asarray(q_start, dtype=np.float64).reshape(1, -1)
    steps = np.diff(np.vstack([prev, positions]), axis=0)
    out = []
    for k, j in _listed(np.nonzero(exceeds(np.abs(steps), max_step_rad)), "step", budget):
        s = float(steps[k, j])
        out.append(
            Violation(
                float(times[k]),
                "step",
                (names[j],),
                s,
                max_step_rad,
                f"{names[j]} jumps {_rad(s)} rad in one tick (max {max_step_rad} rad)",
            )
        )
    return out


def tcp_speed_violations(
    tcp_positions: np.ndarray, dt: float, max_speed: float, tcp_name: str, budget: ListingBudget | None = None
) -> list:
    speed = np.linalg.norm(np.diff(tcp_positions, axis=0), axis=1) / dt
    return [
        Violation(
            float((k + 1) * dt),
            "tcp_speed",
            (tcp_name,),
            float(speed[k]),
            max_speed,
            f"TCP speed {speed[k]:.3f} m/s exceeds {max_speed} m/s",
        )
        for (k,) in _listed(np.nonzero(exceeds(speed, max_speed)), "tcp_speed", budget)
    ]
