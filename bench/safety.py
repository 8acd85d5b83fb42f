"""Safety layer speed: microseconds per configuration check (FK + self + table + workspace walls + 10 boxes +
a 20k-point cloud) on coal and on python-fcl side by side, and milliseconds for the gate to validate a 10 s
trajectory sampled at 250 Hz (limits, derivatives, TCP and sub-sampled collision checks).

    python bench/safety.py [--quick] --out RESULT.json

The scene: 10 boxes (4-8 cm) on the table in front of the robot and 20,000 points sampled on the visible faces
of three bins and a back wall (what a camera sees), octree cells of 1 cm. Configurations: uniform random over the
joint ranges; "free" are the collision-free ones (every pair is tested, the worst case), "random" all of them
(most stop at the first contact, as an OMPL validity checker sees them).
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

# this file is named like the package it measures: keep `python bench/safety.py` from importing itself
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from safety.collision import CollisionWorld  # noqa: E402
from safety.config import SafetyConfig  # noqa: E402
from safety.gate import validate  # noqa: E402
from safety.geometry import WORLD, Primitive, pose  # noqa: E402
from safety.robot_model import RobotModel  # noqa: E402
from safety.trajectory import JointTrajectory  # noqa: E402

TARGETS = {"config_check_us_median": 30.0, "trajectory_10s_250hz_ms": 300.0}
RATE_HZ = 250.0
CLOUD_POINTS = 20_000


def surface_cloud(rng: np.random.Generator, n: int) -> np.ndarray:
    """Points on the top and side faces of three bins and a back wall (base frame)."""
    slabs = [  # (min corner, max corner) of thin faces
        ((0.55, 0.30, 0.0), (0.75, 0.32, 0.15)),
        ((0.55, 0.48, 0.0), (0.75, 0.50, 0.15)),
        ((0.55, 0.30, 0.15), (0.75, 0.50, 0.16)),
        ((0.55, -0.50, 0.0), (0.75, -0.48, 0.12)),
        ((0.55, -0.32, 0.0), (0.75, -0.30, 0.12)),
        ((-0.10, -0.60, 0.0), (0.10, -0.58, 0.20)),
        ((0.90, -0.60, 0.0), (0.92, 0.60, 0.60)),
    ]
    area = np.array([np.prod(np.sort(np.subtract(hi, lo))[1:]) for lo, hi in slabs])
    which = rng.choice(len(slabs), size=n, p=area / area.sum())
    lo = np.array([slabs[k][0] for k in which])
    hi = np.array([slabs[k][1] for k in which])
    return lo + rng.random((n, 3)) * (hi - lo)


def bench_scene(robot: RobotModel, rng: np.random.Generator) -> tuple[list[Primitive], np.ndarray]:
    boxes = []
    for i in range(10):
        size = tuple(rng.uniform(0.04, 0.08, 3))
        center = (rng.uniform(0.3, 0.65), rng.uniform(-0.45, 0.45), size[2] / 2)
        boxes.append(Primitive(f"box{i}", WORLD, "box", size, pose(center)))
    return boxes, surface_cloud(rng, CLOUD_POINTS)


def time_checks(world: CollisionWorld, Q: np.ndarray) -> np.ndarray:
    out = np.empty(len(Q))
    for k, q in enumerate(Q):
        t0 = time.perf_counter()
        world.in_collision(q)
        out[k] = time.perf_counter() - t0
    return out * 1e6


def pick_waypoints(robot: RobotModel, world: CollisionWorld, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """Collision-free IK solutions for gripper-down poses above the table, starting at home."""
    out = [robot.home_q]
    while len(out) < n:
        T = robot.tcp_pose(robot.home_q)
        T[:3, 3] = [rng.uniform(0.3, 0.6), rng.uniform(-0.3, 0.3), rng.uniform(0.15, 0.35)]
        res = robot.ik(T, q_seed=out[-1], accept=lambda q: not world.in_collision(q))
        if res.success:
            out.append(res.q)
    return out


def _move(a: np.ndarray, b: np.ndarray, duration: float) -> np.ndarray:
    s = np.linspace(0.0, 1.0, round(duration * RATE_HZ) + 1)[1:]
    return a + (10 * s**3 - 15 * s**4 + 6 * s**5)[:, None] * (b - a)


def ten_second_trajectory(robot: RobotModel, waypoints: list[np.ndarray], cfg: SafetyConfig) -> JointTrajectory:
    """Minimum-jerk rest-to-rest moves touring the waypoints at 90 % of the joint velocity, acceleration and jerk
    limits (peaks 1.875, 5.77 and 60 times the joint change over T, T^2, T^3), slowed where the TCP would pass
    90 % of its speed limit, then holding still to fill 10 s at 250 Hz: a valid plan as a planner would send it."""
    n_samples = round(10.0 * RATE_HZ) + 1
    rows = [waypoints[0][None]]
    for a, b in itertools.cycle(itertools.pairwise([*waypoints, waypoints[0]])):
        d = float(np.max(np.abs(b - a))) / 0.9
        duration = max(
            1.875 * d / cfg.max_joint_velocity_rad_s,
            np.sqrt(5.774 * d / cfg.max_joint_acceleration_rad_s2),
            np.cbrt(60.0 * d / cfg.max_joint_jerk_rad_s3),
        )
        seg = _move(a, b, duration)
        tcp_speed = np.linalg.norm(np.diff(robot.tcp_positions(np.vstack([a, seg])), axis=0), axis=1) * RATE_HZ
        if tcp_speed.max() > 0.9 * cfg.max_tcp_speed_m_s:
            seg = _move(a, b, duration * tcp_speed.max() / (0.9 * cfg.max_tcp_speed_m_s))
        if sum(len(r) for r in rows) + len(seg) > n_samples:
            break
        rows.append(seg)
    q = np.vstack(rows)
    q = np.vstack([q, np.repeat(q[-1:], n_samples - len(q), axis=0)])
    return JointTrajectory(robot.joint_names, 1.0 / RATE_HZ, q)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer configurations and repeats")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    n_configs, repeats = (500, 2) if args.quick else (5000, 5)
    rng = np.random.default_rng(0)
    robot = RobotModel()
    boxes, cloud = bench_scene(robot, rng)
    worlds, build_ms = {}, {}
    for name in ("coal", "fcl"):
        t0 = time.perf_counter()
        worlds[name] = CollisionWorld(robot, obstacles=boxes, points=cloud, backend=name)
        build_ms[name] = (time.perf_counter() - t0) * 1e3
    Q = rng.uniform(robot.lower, robot.upper, size=(n_configs, 7))
    free = np.array([not worlds["coal"].in_collision(q) for q in Q])
    disagreements = int(sum(worlds["coal"].in_collision(q) != worlds["fcl"].in_collision(q) for q in Q))
    checks = {}
    for name, world in worlds.items():
        us = time_checks(world, Q)
        checks[name] = {
            "median_us_free": float(np.median(us[free])),
            "p95_us_free": float(np.percentile(us[free], 95)),
            "median_us_random": float(np.median(us)),
        }
    trajectory = ten_second_trajectory(robot, pick_waypoints(robot, worlds["coal"], rng, 6), worlds["coal"].config)
    validate_ms, report = {}, None
    for name, world in worlds.items():
        runs = []
        for _ in range(repeats if name == "coal" else 1):
            report = validate(trajectory, world)
            runs.append(report.seconds * 1e3)
        validate_ms[name] = float(np.median(runs))
    # the same plan under a profile with a 4x finer collision resolution: ~4x the collision checks (sub-sampling)
    fine = CollisionWorld(
        robot,
        worlds["coal"].config.model_copy(update={"collision_resolution_rad": 0.0025}),
        obstacles=boxes,
        points=cloud,
    )
    fine_report = validate(trajectory, fine)
    ik_ms = []
    for _ in range(50 if args.quick else 300):
        T = robot.tcp_pose(rng.uniform(robot.lower + 0.05, robot.upper - 0.05))
        t0 = time.perf_counter()
        robot.ik(T)
        ik_ms.append((time.perf_counter() - t0) * 1e3)

    result = {
        "scene": {
            "boxes": len(boxes),
            "cloud_points": len(cloud),
            "octree_cell_m": worlds["coal"].config.cloud_voxel_m,
            "collision_pairs": len(worlds["coal"].scene.pairs),
            "build_ms": build_ms,
        },
        "configurations": {
            "total": n_configs,
            "collision_free": int(free.sum()),
            "backend_disagreements": disagreements,
        },
        "config_check": checks,
        "coal_speedup_over_fcl_free": checks["fcl"]["median_us_free"] / checks["coal"]["median_us_free"],
        "trajectory": {
            "duration_s": trajectory.duration_s,
            "samples": len(trajectory.positions),
            "configurations_checked": report.configurations_checked,
            "valid": report.ok,
            "violation_kinds": sorted(report.kinds()),
        },
        "trajectory_validate_ms": validate_ms,
        "trajectory_validate_ms_fine_resolution": {
            "coal": fine_report.seconds * 1e3,
            "collision_resolution_rad": 0.0025,
            "configurations_checked": fine_report.configurations_checked,
        },
        "ik_ms_median": float(np.median(ik_ms)),
        "quick": args.quick,
    }
    result["targets"] = TARGETS
    result["met"] = {
        "config_check_us_median": checks["coal"]["median_us_free"] <= TARGETS["config_check_us_median"],
        "trajectory_10s_250hz_ms": validate_ms["coal"] <= TARGETS["trajectory_10s_250hz_ms"],
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))

    table = Table(title="safety: collision checks and trajectory gate")
    table.add_column("measure")
    table.add_column("coal (runtime)", justify="right")
    table.add_column("python-fcl", justify="right")
    for key, label in (
        ("median_us_free", "check, free configs, median (us)"),
        ("p95_us_free", "check, free, p95 (us)"),
        ("median_us_random", "check, random configs, median (us)"),
    ):
        table.add_row(label, f"{checks['coal'][key]:.1f}", f"{checks['fcl'][key]:.1f}")
    table.add_row("validate 10 s @ 250 Hz (ms)", f"{validate_ms['coal']:.1f}", f"{validate_ms['fcl']:.1f}")
    table.add_row(
        f"  same, resolution 0.0025 rad ({fine_report.configurations_checked} configs) (ms)",
        f"{fine_report.seconds * 1e3:.1f}",
        "",
    )
    table.add_row("build scene (ms)", f"{build_ms['coal']:.1f}", f"{build_ms['fcl']:.1f}")
    console = Console()
    console.print(table)
    console.print(f"IK median {result['ik_ms_median']:.2f} ms; backend disagreements {disagreements}/{n_configs}")
    for name, ok in result["met"].items():
        console.print(f"{name}: {'met' if ok else 'NOT met'} (target {TARGETS[name]})")


if __name__ == "__main__":
    main()
