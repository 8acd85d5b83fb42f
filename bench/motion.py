"""Motion benchmarks: planning success and time on fixed tabletop queries, trajectory duration against the
time-optimal bound, blended against stop-at-waypoint timing, and streaming period jitter on the sim arm.

    python bench/motion.py [--quick] --out RESULT.json

(a) Scenes: the table, a shelf (top, back and side boards) and 3 random boxes per seed; queries between
    pre-grasp poses above the table, inside the shelf and home (goals from motion.goals). Planning time is
    Planner.plan (direct check, OMPL search, shortcutting, dense re-check); success also needs the timed
    trajectory to pass the safety gate.
(b) Collision-free point-to-point moves: TrajectoryTimer duration (sampled at the control rate) over the Ruckig
    time-optimal duration at the full joint limits on the same straight line. The TCP speed cap, a further
    constraint the bound ignores, is reported separately.
(c) Planned paths with interior waypoints: blended duration over the duration stopping at every planned waypoint.
    Blended = corners cut (Planner.smooth, each cut densely checked) and crossed at speed (TrajectoryTimer
    blend, gate-accepted); blend_only_duration_ratio crosses the planned waypoints themselves, uncut.
(d) A 250 Hz trajectory streamed to the real-time sim arm: |period - 4 ms| percentiles.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from itertools import pairwise
from pathlib import Path

# this file is named like the package it measures: keep `python bench/motion.py` from importing itself
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402
from ruckig import InputParameter, Ruckig, Synchronization, Trajectory  # noqa: E402

from drivers.sim import SimWorld  # noqa: E402
from drivers.sim.arm import SimArm  # noqa: E402
from motion.approval import approve, gate_check  # noqa: E402
from motion.executor import Executor, ExecutorConfig  # noqa: E402
from motion.goals import GoalError, ik_goals  # noqa: E402
from motion.limits import MotionLimits  # noqa: E402
from motion.planner import Planner, PlanningError  # noqa: E402
from motion.timing import TrajectoryTimer  # noqa: E402
from runtime.config import load_profile  # noqa: E402
from safety.collision import CollisionWorld  # noqa: E402
from safety.geometry import Primitive, pose  # noqa: E402
from safety.robot_model import RobotModel  # noqa: E402

HOME_TCP_XY = np.array([0.4, 0.0])  # where the gripper hangs at home_q
CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim.yaml"
TARGETS = {
    "planning_success_rate": 0.99,
    "planning_time_median_s": 0.050,
    "p2p_duration_ratio": 1.02,
    "blend_duration_ratio": 0.80,
    "jitter_p99_s_250hz": 0.001,
}


def shelf() -> list[Primitive]:
    """Open towards the robot: a top board at 0.32 m, back and side boards, 0.5-0.72 m out, y 0.22-0.58 m."""
    boards = [
        ("shelf_top", (0.24, 0.38, 0.02), (0.61, 0.40, 0.33)),
        ("shelf_back", (0.02, 0.38, 0.34), (0.73, 0.40, 0.17)),
        ("shelf_left", (0.24, 0.02, 0.34), (0.61, 0.59, 0.17)),
        ("shelf_right", (0.24, 0.02, 0.34), (0.61, 0.21, 0.17)),
    ]
    return [Primitive(name, "world", "box", size, pose(center)) for name, size, center in boards]


def random_boxes(rng: np.random.Generator) -> list[Primitive]:
    out: list[Primitive] = []
    while len(out) < 3:
        size = rng.uniform([0.05, 0.05, 0.06], [0.12, 0.12, 0.22])
        xy = rng.uniform([0.3, -0.45], [0.65, 0.15])
        others = [b.T_link_geom[:2, 3] for b in out] + [HOME_TCP_XY]  # apart, and clear of the arm at home
        if any(np.linalg.norm(xy - c) < 0.15 for c in others):
            continue
        out.append(Primitive(f"box{len(out)}", "world", "box", tuple(size), pose((*xy, size[2] / 2))))
    return out


def top_down(xyz, yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]]
    T[:3, 3] = xyz
    return T


def into_shelf(y: float, z: float) -> np.ndarray:
    """Gripper horizontal, pointing +x into the shelf."""
    T = np.eye(4)
    T[:3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
    T[:3, 3] = (0.56, y, z)
    return T


def goal_poses(rng: np.random.Generator, boxes: list[Primitive], n: int) -> list[np.ndarray]:
    """Pre-grasp poses 10-15 cm above random boxes or table spots, and some inside the shelf."""
    poses = []
    for k in range(n):
        if k % 3 == 2:
            poses.append(into_shelf(rng.uniform(0.33, 0.47), rng.uniform(0.1, 0.2)))
        elif k % 3 == 1:
            b = boxes[rng.integers(len(boxes))]
            top = b.T_link_geom[:3, 3] + [0, 0, b.size[2] / 2 + rng.uniform(0.1, 0.15)]
            poses.append(top_down(top, rng.uniform(-np.pi / 2, np.pi / 2)))
        else:
            xy = rng.uniform([0.25, -0.45], [0.6, 0.1])
            poses.append(top_down((*xy, rng.uniform(0.12, 0.3)), rng.uniform(-np.pi / 2, np.pi / 2)))
    return poses


def time_optimal(q0: np.ndarray, q1: np.ndarray, limits: MotionLimits) -> float:
    inp = InputParameter(7)
    inp.current_position, inp.target_position = q0, q1
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = limits.velocity, limits.acceleration, limits.jerk
    inp.synchronization = Synchronization.Phase
    traj = Trajectory(7)
    Ruckig(7).calculate(inp, traj)
    return traj.duration


def planning(scenes: int, per_scene: int, robot: RobotModel, profile, limits: MotionLimits) -> dict:
    dt = 1.0 / profile.robot.control_rate_hz
    joint_only = TrajectoryTimer(limits, dt, robot.joint_names)
    timer = TrajectoryTimer(limits, dt, robot.joint_names, robot.tcp_positions, profile.safety.max_tcp_speed_m_s)
    times, ok, methods, failures = [], [], [], []
    p2p, p2p_capped, blend, smooth_blend, smooth_ok = [], [], [], [], []
    for seed in range(scenes):
        rng = np.random.default_rng(seed)
        boxes = random_boxes(rng)
        world = CollisionWorld(robot.copy(), profile.safety, obstacles=shelf() + boxes)
        planner = Planner(world, limits)
        goals = [robot.home_q]
        for T in goal_poses(rng, boxes, per_scene + 4):
            try:
                goals.append(ik_goals(world, limits, T, robot.home_q, max_solutions=3, attempts=12)[0].q)
            except GoalError:
                continue
            if len(goals) == per_scene:
                break
        goals.append(robot.home_q)
        for q0, q1 in pairwise(goals):
            t0 = time.perf_counter()
            try:
                path = planner.plan(q0, q1)
            except PlanningError as e:
                times.append(time.perf_counter() - t0)
                ok.append(False)
                failures.append(str(e)[:200])
                continue
            times.append(path.planning_time_s)
            methods.append(path.method)
            stop = timer.time([path.waypoints])
            report = approve_ok(stop, world, q0)
            ok.append(report)
            if not report:
                failures.append(f"gate refused the planned path (seed {seed})")
            if path.method == "direct":
                bound = time_optimal(q0, q1, limits)
                p2p.append(joint_only.time([path.waypoints]).duration_s / bound)
                p2p_capped.append(stop.duration_s / bound)
            elif len(path.waypoints) >= 3:
                check = gate_check(world, q0)
                blended = timer.time([path.waypoints], blend=True, check=check)
                smoothed = timer.time([planner.smooth(path.waypoints)], blend=True, check=check)
                smooth_ok.append(approve_ok(smoothed, world, q0))
                blend.append(blended.duration_s / stop.duration_s)
                smooth_blend.append(smoothed.duration_s / stop.duration_s)
    times_arr = np.array(times)
    return {
        "queries": len(times),
        "planning_success_rate": float(np.mean(ok)),
        "planning_time_median_s": float(np.median(times_arr)),
        "planning_time_p95_s": float(np.percentile(times_arr, 95)),
        "direct_share": float(np.mean([m == "direct" for m in methods])),
        "p2p_moves": len(p2p),
        "p2p_duration_ratio": float(np.mean(p2p)),
        "p2p_duration_ratio_max": float(np.max(p2p)),
        "p2p_duration_ratio_with_tcp_cap": float(np.mean(p2p_capped)),
        "multi_waypoint_paths": len(blend),
        "blend_duration_ratio": float(np.median(smooth_blend)) if blend else float("nan"),
        "blend_duration_ratio_mean": float(np.mean(smooth_blend)) if blend else float("nan"),
        "blend_gate_pass_rate": float(np.mean(smooth_ok)) if blend else float("nan"),
        "blend_only_duration_ratio": float(np.median(blend)) if blend else float("nan"),
        "failures": failures,
    }


def approve_ok(traj, world, q0) -> bool:
    from motion.approval import GateRefused

    try:
        approve(traj, world, q_current=q0)
        return True
    except GateRefused:
        return False


def jitter_250hz(robot: RobotModel, seconds: float) -> dict:
    profile = load_profile(CONFIG, {"sim": {"realtime": True}, "robot": {"control_rate_hz": 250}})
    world = SimWorld(profile.sim, profile.camera)
    arm = SimArm(world, 250)
    arm.connect()
    try:
        limits = MotionLimits.from_config(profile.safety, robot.spec, speed_scale=0.5)
        timer = TrajectoryTimer(limits, 1 / 250, robot.joint_names, robot.tcp_positions, 1.0)
        q0 = arm.read_state().q
        swing = np.array([0.8, 0.3, 0.0, 0.3, 0.0, -0.3, 0.8])
        legs = max(2, int(seconds / 1.2))
        waypoints = np.array([q0 + swing * (k % 2) for k in range(legs + 1)])
        approved = approve(timer.time([waypoints]), CollisionWorld(robot.copy(), profile.safety), q_current=q0)
        report = Executor(arm, ExecutorConfig.from_configs(profile.robot, profile.safety), limits).execute(approved)
    finally:
        arm.close()
        world.stop()
    return {
        "jitter_ticks": report.ticks,
        "jitter_status": report.status,
        "jitter_p50_s_250hz": report.jitter.p50_s,
        "jitter_p99_s_250hz": report.jitter.p99_s,
        "jitter_max_s_250hz": report.jitter.max_s,
        "late_ticks_250hz": report.late_ticks,
        "jitter_realtime_priority": report.realtime_priority,
        "tracking_error_max_rad_250hz": report.max_tracking_error_rad,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="2 scenes and a short stream")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    profile = load_profile(CONFIG, {"sim": {"realtime": False}})
    robot = RobotModel()
    limits = MotionLimits.from_config(profile.safety, robot.spec)
    result = planning(2 if args.quick else 10, 5 if args.quick else 6, robot, profile, limits)
    result |= jitter_250hz(robot, 2.0 if args.quick else 10.0)
    met = {
        "planning_success_rate": result["planning_success_rate"] >= TARGETS["planning_success_rate"],
        "planning_time_median_s": result["planning_time_median_s"] <= TARGETS["planning_time_median_s"],
        "p2p_duration_ratio": result["p2p_duration_ratio"] <= TARGETS["p2p_duration_ratio"],
        "blend_duration_ratio": result["blend_duration_ratio"] <= TARGETS["blend_duration_ratio"],
        "jitter_p99_s_250hz": result["jitter_p99_s_250hz"] <= TARGETS["jitter_p99_s_250hz"],
    }
    result |= {"quick": args.quick, "targets": TARGETS, "met": met}
    table = Table(title="motion")
    for column in ("measure", "value", "target", "met"):
        table.add_column(column)
    for key, value in result.items():
        if isinstance(value, int | float) and not isinstance(value, bool):
            target = TARGETS.get(key)
            table.add_row(key, f"{value:.4g}", "" if target is None else f"{target:g}", str(met.get(key, "")))
    Console().print(table)
    for failure in result["failures"]:
        Console().print(f"[red]failed:[/red] {failure}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
