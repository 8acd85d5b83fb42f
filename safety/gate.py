"""The trajectory gate: nothing is streamed to the arm unless `validate` returns a report with ok == True.

    report = validate(trajectory, world)          # world: CollisionWorld (robot, safety config, scene)
    if not report.ok: refuse(report.reason())     # report.violations lists every violation

Checks every sample for joint limits (with margin), velocity, acceleration, jerk, per-tick step, TCP speed, and
the TCP inside the workspace and outside keep-out boxes; checks the motion between samples for self-collision,
collision, workspace and keep-out of every (padded) robot primitive and the held object, sub-sampled so that no
joint moves more than config.collision_resolution_rad between two checked configurations. The gripper width
follows the trajectory's gripper events (it changes at the event time).
"""

from __future__ import annotations

import time

import numpy as np

from safety.collision import CollisionWorld
from safety.limits import derivative_violations, joint_limit_violations, step_violations, tcp_speed_violations
from safety.trajectory import JointTrajectory
from safety.violations import GateReport, Violation


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


def subsample(positions: np.ndarray, dt: float, resolution_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Configurations to collision-check: every sample plus evenly spaced points between consecutive samples so
    that no joint moves more than resolution_rad between two of them. Returns (configs, times)."""
    steps = np.diff(positions, axis=0)
    counts = np.maximum(1, np.ceil(np.max(np.abs(steps), axis=1, initial=0.0) / resolution_rad - 1e-9)).astype(int)
    seg = np.repeat(np.arange(len(steps)), counts)
    frac = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + 1) / np.repeat(counts, counts)
    configs = np.vstack([positions[:1], positions[seg] + frac[:, None] * steps[seg]])
    times = np.concatenate([[0.0], (seg + frac) * dt])
    return configs, times


def _tcp_region_violations(tcp: np.ndarray, times: np.ndarray, world: CollisionWorld) -> list[Violation]:
    cfg, name = world.config, world.robot.tcp_frame
    out = []
    lo, hi = np.asarray(cfg.workspace.min_m), np.asarray(cfg.workspace.max_m)
    for k in np.flatnonzero(np.any((tcp < lo) | (tcp > hi), axis=1)):
        p = np.round(tcp[k], 4).tolist()
        out.append(
            Violation(float(times[k]), "workspace", (name,), None, None, f"TCP at {p} m is outside the workspace")
        )
    for box in cfg.keep_out:
        inside = np.all((tcp >= box.min_m) & (tcp <= box.max_m), axis=1)
        for k in np.flatnonzero(inside):
            p = np.round(tcp[k], 4).tolist()
            label = f"keep_out:{box.name}"
            out.append(Violation(float(times[k]), "keep_out", (name, label), None, None, f"TCP at {p} m is in {label}"))
    return out


def _collision_violations(configs, times, widths, world: CollisionWorld) -> list[Violation]:
    out = []
    width = None
    for q, t, w in zip(configs, times, widths, strict=True):
        if w != width:
            world.set_gripper_width(w)
            width = w
        if world.in_collision(q):
            for c in world.check(q):
                detail = f"{c.first} touches {c.second} (padding {world.config.padding_m} m)"
                out.append(Violation(float(t), c.kind, (c.first, c.second), None, None, detail))
    return out


def validate(trajectory: JointTrajectory, world: CollisionWorld, *, q_current: np.ndarray | None = None) -> GateReport:
    """Check the whole trajectory against world.config and world's scene; returns every violation, sorted by
    time. q_current (the arm's present position) adds the step from it to the first sample."""
    t0 = time.perf_counter()
    robot, cfg = world.robot, world.config
    if tuple(trajectory.joint_names) != robot.joint_names:
        raise TrajectoryError(
            f"trajectory joints {list(trajectory.joint_names)} != robot joints {list(robot.joint_names)}"
        )
    q, dt, names = trajectory.positions, trajectory.dt, robot.joint_names
    times = trajectory.times
    violations = joint_limit_violations(q, times, names, robot.lower, robot.upper, cfg.joint_margin_rad)
    violations += derivative_violations(q, dt, names, cfg, robot.velocity_limits)
    violations += step_violations(q, times, names, cfg.max_joint_step_rad, q_current)
    tcp = robot.tcp_positions(q)
    violations += tcp_speed_violations(tcp, dt, cfg.max_tcp_speed_m_s, robot.tcp_frame)
    violations += _tcp_region_violations(tcp, times, world)
    configs, sub_times = subsample(q, dt, cfg.collision_resolution_rad)
    start_width = world.gripper_width_m
    widths = gripper_widths(trajectory, sub_times, start_width, world)
    try:
        violations += _collision_violations(configs, sub_times, widths, world)
    finally:
        world.set_gripper_width(start_width)
    violations.sort(key=lambda v: v.time_s)
    return GateReport(tuple(violations), len(q), len(configs), time.perf_counter() - t0)


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
