"""`goalvla demo`: drive the simulated arm through a few postures and save a capture at each.

A smoke test a person can watch: every posture is reached by a minimum-jerk move streamed at the control rate,
and each move is checked before it is streamed (joint limits with margin, speed, per-tick step).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from motion.interpolate import minimum_jerk_path
from runtime.capture import save_frame
from runtime.config import Profile
from runtime.devices import open_devices

# Offsets from the home posture [rad]: look left, reach forward-low, look right, home.
DEMO_OFFSETS: dict[str, tuple[float, ...]] = {
    "left": (0.6, 0.1, 0.0, 0.15, 0.0, 0.05, 0.3),
    "forward": (0.0, 0.35, 0.0, 0.1, 0.0, -0.2, 0.0),
    "right": (-0.6, 0.1, 0.0, 0.15, 0.0, 0.05, -0.3),
    "home": (0.0,) * 7,
}


class DemoRefused(RuntimeError):
    pass


def check_path(
    path: np.ndarray, q_start: np.ndarray, lower: np.ndarray, upper: np.ndarray, margin: float, max_step: float
) -> None:
    """Refuse a path that leaves the joint limits (minus margin) or steps further than max_step per tick."""
    low, high = lower + margin, upper - margin
    bad = np.argwhere((path < low) | (path > high))
    if bad.size:
        k, j = bad[0]
        raise DemoRefused(f"sample {k}: joint {j + 1} = {path[k, j]:.3f} rad outside [{low[j]:.3f}, {high[j]:.3f}]")
    steps = np.abs(np.diff(np.vstack([q_start, path]), axis=0))
    if steps.max() > max_step:
        k, j = np.unravel_index(np.argmax(steps), steps.shape)
        raise DemoRefused(f"sample {k}: joint {j + 1} steps {steps[k, j]:.4f} rad > {max_step} rad per tick")


def stream(arm, path: np.ndarray, rate_hz: float) -> None:
    """Send one set-point per tick on an absolute schedule (no drift)."""
    period = 1.0 / rate_hz
    t_next = time.perf_counter()
    for q in path:
        arm.servo(q)
        t_next += period
        time.sleep(max(0.0, t_next - time.perf_counter()))


def run_demo(profile: Profile, out_dir: Path) -> list[Path]:
    saved: list[Path] = []
    rate = profile.robot.control_rate_hz
    limits = profile.safety
    with open_devices(profile) as dev:
        spec = dev.world.spec
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
                path = minimum_jerk_path(q_from, home + np.asarray(offset), rate, 0.5 * limits.max_joint_velocity_rad_s)
                check_path(path, q_from, spec.lower, spec.upper, limits.joint_margin_rad, limits.max_joint_step_rad)
                stream(dev.arm, path, rate)
                time.sleep(0.3)  # settle before the picture
                frame = dev.camera.read().with_extrinsics(dev.T_base_camera)
                saved += save_frame(frame, out_dir / f"{len(saved) // 3:02d}_{name}")
                progress.advance(task)
    return saved
