"""`goalvla calibrate hand-eye`: the operator-facing side of the hand-eye procedure (devices, confirm, report).

On a sim profile the board is put into the MuJoCo world (on the gripper for eye-to-hand, on the table with a
flange camera for eye-in-hand) and rendered at 1280x720 like the lab camera; the result is compared with the
simulation's ground truth.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

from calibration.board import CharucoBoardSpec
from calibration.handeye import Mode
from calibration.mover import CalibrationRefused, GatedMover
from calibration.session import (
    Geometry,
    HandEyeOutcome,
    ViewCollector,
    board_as_held_object,
    judge,
    nominal_geometry,
    plan_views,
)
from calibration.store import save_calibration
from motion.executor import ExecutorConfig
from motion.limits import MotionLimits
from runtime.config import Profile
from runtime.devices import open_devices
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

SIM_RENDER_SIZE = (1280, 720)
SIM_TEXTURE_PX_PER_SQUARE = 96


def sim_overrides(mode: Mode, board: CharucoBoardSpec, geometry: Geometry, texture_dir: Path) -> dict:
    """Profile overrides that put the board (and for eye-in-hand the camera) where the procedure expects them."""
    texture = texture_dir / f"{board.name}.png"
    cv2.imwrite(str(texture), board.image(SIM_TEXTURE_PX_PER_SQUARE))
    T = geometry.T_flange_board if mode == "eye_to_hand" else geometry.T_base_board
    camera: dict = {"width_px": SIM_RENDER_SIZE[0], "height_px": SIM_RENDER_SIZE[1]}
    if mode == "eye_in_hand":
        camera["sim"] = {"mount": "flange"}
    sim_board = {
        "texture": str(texture),
        "size_m": list(board.size_m),
        "mount": "flange" if mode == "eye_to_hand" else "table",
        "xyz_m": T[:3, 3].tolist(),
        "rpy_rad": Rotation.from_matrix(T[:3, :3]).as_euler("xyz").tolist(),
    }
    return {"camera": camera, "sim": {"board": sim_board}}


def report(outcome: HandEyeOutcome, console: Console) -> None:
    views = Table(title="per-view residuals (predicted vs measured board pose)")
    for column in ("view", "mm", "deg"):
        views.add_column(column, justify="right")
    best = outcome.result.best
    for k, (mm, deg) in enumerate(zip(best.residual_mm, best.residual_deg, strict=True), start=1):
        views.add_row(str(k), f"{mm:.2f}", f"{deg:.3f}")
    console.print(views)
    methods = Table(title="methods (lowest score kept: median mm + 10 x median deg)")
    for column in ("method", "median mm", "median deg", "score"):
        methods.add_column(column, justify="right")
    for c in sorted(outcome.result.candidates, key=lambda c: c.score):
        methods.add_row(
            c.method, f"{np.median(c.residual_mm):.2f}", f"{np.median(c.residual_deg):.3f}", f"{c.score:.2f}"
        )
    console.print(methods)
    console.print(
        f"kept [bold]{best.method}[/bold] over {outcome.views} views, rotation spread "
        f"{outcome.rotation_spread_deg:.1f} deg"
    )


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    E = np.linalg.inv(T_true) @ T_est
    return 1000 * float(np.linalg.norm(E[:3, 3])), float(np.degrees(Rotation.from_matrix(E[:3, :3]).magnitude()))


def run_hand_eye(
    profile: Profile,
    load: Callable[[dict], Profile],
    board: CharucoBoardSpec,
    mode: Mode,
    out: Path,
    confirm: Callable[[str], bool],
    console: Console,
) -> int:
    """Returns the exit code: 0 stored, 3 refused (nothing stored). `load(overrides)` re-reads the profile."""
    cfg = profile.calibration.hand_eye
    sim = profile.robot.simulated
    geometry = nominal_geometry(mode, board, cfg, profile.camera.sim if sim else None)
    with tempfile.TemporaryDirectory() as texture_dir:
        if sim:
            profile = load(sim_overrides(mode, board, geometry, Path(texture_dir)))
        with open_devices(profile, with_extrinsics=False) as devices:
            world = CollisionWorld(RobotModel(), profile.safety)
            if mode == "eye_to_hand":
                world.set_held_object(board_as_held_object(board, geometry, world))
            speed = cfg.speed_fraction * profile.safety.max_joint_velocity_rad_s
            limits = MotionLimits.from_config(profile.safety, world.robot.spec)
            mover = GatedMover(
                devices.arm, world, ExecutorConfig.from_configs(profile.robot, profile.safety), limits, speed
            )
            q_start = devices.arm.read_state().q
            console.print(f"planning {cfg.poses} views ({mode.replace('_', '-')}) ...")
            plan = plan_views(mode, board, cfg, geometry, mover, q_start)
            if len(plan.q) < cfg.min_views:
                console.print(
                    f"[red]only {len(plan.q)} safe views found (need {cfg.min_views}): move the board "
                    "target (calibration.hand_eye.target_centre_m / board_on_table_m) or widen the spread"
                )
                return 3
            travel = max(float(np.max(np.abs(q - q_start))) for q in plan.q)
            question = (
                f"The arm will move through {len(plan.q)} views at up to {speed:.2f} rad/s (largest joint "
                f"change {np.degrees(travel):.0f} deg from now). Area clear and e-stop at hand?"
            )
            if not confirm(question):
                console.print("cancelled; the arm did not move")
                return 3
            try:
                A, views = ViewCollector(mover, devices.camera, board, cfg.settle_s, console.print).collect(plan)
                mover.move_to(q_start)
            except CalibrationRefused as e:
                console.print(f"[red]{e}")
                return 3
            outcome = judge(mode, A, views, devices.camera.intrinsics.K, board, cfg)
            truth = None
            if devices.world is not None:
                truth = devices.world.T_world_camera if mode == "eye_to_hand" else devices.world.T_flange_camera
    report(outcome, console)
    if truth is not None:
        mm, deg = pose_error(outcome.result.best.X, truth)
        console.print(f"sim ground truth: error {mm:.3f} mm, {deg:.4f} deg")
    if outcome.problems:
        console.print("[red]refused, nothing written: " + "; ".join(outcome.problems))
        return 3
    save_calibration(outcome.calibration, out)
    console.print(
        f"[green]wrote {out}[/green] (median residual {outcome.result.median_mm:.2f} mm, "
        f"{outcome.result.median_deg:.3f} deg)"
    )
    return 0
