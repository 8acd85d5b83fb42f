"""`goalvla demo`: drive the simulated arm through a few postures and save a capture at each.

A smoke test a person can watch, on the same motion path as a real run: each posture is planned
(motion.planner: direct move when collision-free), timed by Ruckig inside the safety limits at half speed
(motion.timing), approved by the safety gate (motion.approval) and streamed at the control rate by the
supervised executor (motion.executor). A refusal anywhere stops the demo with the reason.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from motion.approval import GateRefused, approve
from motion.executor import ExecutionRefused, Executor, ExecutorConfig
from motion.limits import MotionLimits
from motion.planner import Planner, PlanningError
from motion.timing import TimingError, TrajectoryTimer
from runtime.commands.capture import save_frame
from runtime.config import Profile
from runtime.devices import open_devices
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

# Offsets from the home posture [rad]: look left, reach forward-low, look right, home.
DEMO_OFFSETS: dict[str, tuple[float, ...]] = {
    "left": (0.6, 0.1, 0.0, 0.15, 0.0, 0.05, 0.3),
    "forward": (0.0, 0.35, 0.0, 0.1, 0.0, -0.2, 0.0),
    "right": (-0.6, 0.1, 0.0, 0.15, 0.0, 0.05, -0.3),
    "home": (0.0,) * 7,
}
DEMO_SPEED_SCALE = 0.5


class DemoRefused(RuntimeError):
    pass


def run_demo(profile: Profile, out_dir: Path) -> list[Path]:
    saved: list[Path] = []
    robot = RobotModel()
    world = CollisionWorld(robot, profile.safety)
    limits = MotionLimits.from_config(profile.safety, robot.spec, DEMO_SPEED_SCALE)
    planner = Planner(world, limits)
    timer = TrajectoryTimer(
        limits,
        1.0 / profile.robot.control_rate_hz,
        robot.joint_names,
        robot.tcp_positions,
        profile.safety.max_tcp_speed_m_s,
    )
    with open_devices(profile) as dev:
        executor = Executor(dev.arm, ExecutorConfig.from_configs(profile.robot, profile.safety), limits, dev.gripper)
        home = dev.arm.read_state().q
        columns = (
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total}"),
            TimeElapsedColumn(),
        )
        with Progress(*columns) as progress:
            task = progress.add_task("demo", total=len(DEMO_OFFSETS))
            for name, offset in DEMO_OFFSETS.items():
                progress.update(task, description=f"moving to {name:8s}")
                q_from = dev.arm.read_state().q
                try:
                    path = planner.plan(q_from, home + np.asarray(offset))
                    approved = approve(timer.time([path.waypoints]), world, q_current=q_from)
                    report = executor.execute(approved)
                except (PlanningError, TimingError, GateRefused, ExecutionRefused) as e:
                    raise DemoRefused(f"move to {name}: {e}") from e
                if report.status != "completed":
                    raise DemoRefused(f"move to {name}: {report.status}: {report.reason}")
                time.sleep(0.3)  # settle before the picture
                frame = dev.capture()
                saved += save_frame(frame, out_dir / f"{len(saved) // 3:02d}_{name}")
                progress.advance(task)
    return saved
