"""The trajectory gate: nothing is streamed to the arm unless `validate` returns a report with ok == True.

    report = validate(trajectory, world)          # world: CollisionWorld (robot, safety config, scene)
    if not report.ok: refuse(report.reason())     # report.violations lists every violation

Checks every sample for joint limits (with margin), velocity, acceleration, jerk, per-tick step, TCP speed, and
the TCP inside the workspace and outside keep-out boxes; checks the motion between samples for self-collision,
collision, workspace and keep-out of every (padded) robot primitive and the held object, sub-sampled so that no
joint moves more than config.collision_resolution_rad between two checked configurations. The gripper width
follows the trajectory's gripper events (it changes at the event time).

Absurd input is refused without being expanded: a segment on which a joint moves more than its whole range is
a jump (a step and joint-limit violation) and is not sub-sampled; the collision checks are generated and run in
chunks, at most max_checks of them; a trajectory of more than MAX_SAMPLES samples is refused unchecked; at most
MAX_LISTED_PER_KIND violations of a kind are listed. So validate's time and memory are bounded for any input.
"""

from __future__ import annotations

import time

import numpy as np

from safety.collision import CollisionWorld
from safety.limits import derivative_violations, joint_limit_violations, step_violations, tcp_speed_violations
from safety.trajectory import JointTrajectory
from safety.violations import GateReport, ListingBudget, Violation

MAX_SAMPLES = 200_000  # 13 min at 250 Hz: longer is not one motion, and the per-sample checks stay ~1 s
MAX_COLLISION_CHECKS = 1_000_000  # configurations collision-checked per trajectory (~15-30 s)
CHECK_CHUNK = 20_000  # configurations interpolated and checked at a time (~1 MB)


class TrajectoryError(ValueError):
    """The trajectory cannot be checked at all (wrong joints); the message says what is wrong."""


def gripper_widths(trajectory: JointTrajectory, times: np.ndarray, start_width_m: float, world: CollisionWorld):
    """Commanded finger gap at each time: the start width until the first open/close event, then the event's."""
    g = world.robot.spec.gripper
    widths = np.full(len(times), start_width_m)
    for ev in sorted(trajectory.gripper_events, key=lambda e: e.time_s):
        if ev.kind == "wait":
            continue
        width = ev.width_m or (g.max_width_m if ev.kind == "open" else g.min_width_m)
        widths[times >= ev.time_s - 1e-12] = width
    return widths


def subsample_counts(positions: np.ndarray, resolution_rad: float, jump_rad) -> np.ndarray:
    """Configurations checked per segment (sample k -> k + 1, its end included): enough that no joint moves more
    than resolution_rad between two. A segment on which some joint moves more than jump_rad (per joint) is a
    jump, not a motion: it gets its end sample only, never millions of sub-samples (the gate refuses it as a step
    and joint-limit violation anyway). Counts are capped at MAX_COLLISION_CHECKS + 1, so their sum fits."""
    steps = np.abs(np.diff(positions, axis=0))
    jump = np.any(~(steps <= jump_rad), axis=1)  # NaN and inf differences included
    largest = np.where(jump, 0.0, np.max(steps, axis=1, initial=0.0))
    counts = np.minimum(np.ceil(largest / resolution_rad - 1e-9), MAX_COLLISION_CHECKS + 1)
    return np.maximum(1, counts).astype(np.int64)


def interpolated(positions: np.ndarray, dt: float, counts: np.ndarray, first: int, stop: int):
    """Checked configurations first..stop-1 of the trajectory, numbered from 0 (the first sample); segment s's
    counts[s] configurations end exactly at sample s + 1. Returns (configs, times)."""
    if len(counts) == 0:
        return positions[:1], np.zeros(1)
    ends = np.cumsum(counts)
    index = np.arange(first, stop)
    seg = np.minimum(np.searchsorted(ends, index, side="left"), len(counts) - 1)
    frac = (index - (ends[seg] - counts[seg])) / counts[seg]
    configs = (1.0 - frac)[:, None] * positions[seg] + frac[:, None] * positions[seg + 1]
    return configs, (seg + frac) * dt


def subsample(
    positions: np.ndarray, dt: float, resolution_rad: float, jump_rad=np.inf
) -> tuple[np.ndarray, np.ndarray]:
    """Configurations to collision-check: every sample plus evenly spaced points between consecutive samples so
    that no joint moves more than resolution_rad between two of them (jumps beyond jump_rad: their ends only).
    Returns (configs, times); the gate itself takes them in bounded chunks."""
    counts = subsample_counts(positions, resolution_rad, jump_rad)
    return interpolated(positions, dt, counts, 0, int(counts.sum()) + 1)


def _tcp_region_violations(tcp: np.ndarray, times: np.ndarray, world: CollisionWorld, budget=None) -> list[Violation]:
    cfg, name = world.config, world.robot.tcp_frame
    out = []
    lo, hi = np.asarray(cfg.workspace.min_m), np.asarray(cfg.workspace.max_m)
    outside = np.flatnonzero(np.any((tcp < lo) | (tcp > hi), axis=1))
    for k in outside[: len(outside) if budget is None else budget.take("workspace", len(outside))]:
        p = np.round(tcp[k], 4).tolist()
        out.append(
            Violation(float(times[k]), "workspace", (name,), None, None, f"TCP at {p} m is outside the workspace")
        )
    for box in cfg.keep_out:
        inside = np.flatnonzero(np.all((tcp >= box.min_m) & (tcp <= box.max_m), axis=1))
        for k in inside[: len(inside) if budget is None else budget.take("keep_out", len(inside))]:
            p = np.round(tcp[k], 4).tolist()
            label = f"keep_out:{box.name}"
            out.append(Violation(float(times[k]), "keep_out", (name, label), None, None, f"TCP at {p} m is in {label}"))
    return out


def _collision_violations(configs, times, widths, world: CollisionWorld, budget=None) -> list[Violation]:
    out = []
    width = None
    for q, t, w in zip(configs, times, widths, strict=True):
        if w != width:
            world.set_gripper_width(w)
            width = w
        if world.in_collision(q):
            if budget is not None:
                if budget.configurations_left <= 0:
                    budget.omitted += 1
                    continue
                budget.configurations_left -= 1
            for c in world.check(q):
                if budget is None or budget.take(c.kind, 1):
                    detail = f"{c.first} touches {c.second} (padding {world.config.padding_m} m)"
                    out.append(Violation(float(t), c.kind, (c.first, c.second), None, None, detail))
    return out


def _motion_violations(trajectory: JointTrajectory, world: CollisionWorld, budget, max_checks: int):
    """Collisions of the sub-sampled motion, checked CHECK_CHUNK configurations at a time and at most max_checks
    in all; beyond that one `unchecked` violation says where checking stopped. Returns (violations, checked)."""
    q, dt, cfg, robot = trajectory.positions, trajectory.dt, world.config, world.robot
    counts = subsample_counts(q, cfg.collision_resolution_rad, robot.upper - robot.lower)
    total = int(counts.sum()) + 1
    checked = min(total, max_checks)
    start_width = world.gripper_width_m
    out: list[Violation] = []
    try:
        for first in range(0, checked, CHECK_CHUNK):
            configs, times = interpolated(q, dt, counts, first, min(first + CHECK_CHUNK, checked))
            widths = gripper_widths(trajectory, times, start_width, world)
            out += _collision_violations(configs, times, widths, world, budget)
    finally:
        world.set_gripper_width(start_width)
    if total > checked:
        _, (t,) = interpolated(q, dt, counts, checked, checked + 1)
        out.append(
            Violation(
                float(t),
                "unchecked",
                (),
                float(total),
                float(max_checks),
                f"the motion between samples needs {total:,} collision checks at collision_resolution_rad "
                f"{cfg.collision_resolution_rad} rad, more than the gate's {max_checks:,}: not checked from "
                f"t={t:.3f} s (split the trajectory or move slower)",
            )
        )
    return out, checked


def validate(
    trajectory: JointTrajectory,
    world: CollisionWorld,
    *,
    q_current: np.ndarray | None = None,
    max_checks: int = MAX_COLLISION_CHECKS,
) -> GateReport:
    """Check the whole trajectory against world.config and world's scene; returns every violation, sorted by
    time (at most MAX_LISTED_PER_KIND of each kind listed, the rest counted). q_current (the arm's present
    position) adds the step from it to the first sample. Time and memory are bounded whatever the input: more
    than MAX_SAMPLES samples or more than max_checks collision checks is an `unchecked` violation."""
    t0 = time.perf_counter()
    robot, cfg = world.robot, world.config
    if tuple(trajectory.joint_names) != robot.joint_names:
        raise TrajectoryError(
            f"trajectory joints {list(trajectory.joint_names)} != robot joints {list(robot.joint_names)}"
        )
    q, dt, names = trajectory.positions, trajectory.dt, robot.joint_names
    if len(q) > MAX_SAMPLES:
        detail = f"{len(q):,} samples, more than the gate checks in one trajectory ({MAX_SAMPLES:,}): split it"
        too_long = Violation(0.0, "unchecked", (), float(len(q)), float(MAX_SAMPLES), detail)
        return GateReport((too_long,), len(q), 0, time.perf_counter() - t0)
    budget = ListingBudget()
    times = trajectory.times
    with np.errstate(over="ignore", invalid="ignore"):  # an absurd jump overflows to inf: a violation, no warning
        violations = joint_limit_violations(q, times, names, robot.lower, robot.upper, cfg.joint_margin_rad, budget)
        violations += derivative_violations(q, dt, names, cfg, robot.velocity_limits, budget)
        violations += step_violations(q, times, names, cfg.max_joint_step_rad, q_current, budget)
        tcp = robot.tcp_positions(q)
        violations += tcp_speed_violations(tcp, dt, cfg.max_tcp_speed_m_s, robot.tcp_frame, budget)
        violations += _tcp_region_violations(tcp, times, world, budget)
        motion, checked = _motion_violations(trajectory, world, budget, max_checks)
    violations += motion
    violations.sort(key=lambda v: v.time_s)
    return GateReport(tuple(violations), len(q), checked, time.perf_counter() - t0, budget.omitted)


def check_configuration(q: np.ndarray, world: CollisionWorld) -> list[Violation]:
    """Joint limits, TCP region and collisions of one configuration (time 0), e.g. an IK goal before planning."""
    q = np.asarray(q, dtype=np.float64).reshape(1, -1)
    robot = world.robot
    times = np.zeros(1)
    out = joint_limit_violations(q, times, robot.joint_names, robot.lower, robot.upper, world.config.joint_margin_rad)
    out += _tcp_region_violations(robot.tcp_positions(q), times, world)
    out += _collision_violations(q, times, [world.gripper_width_m], world)
    return out


__all__ = ["GateReport", "TrajectoryError", "Violation", "check_configuration", "validate"]
