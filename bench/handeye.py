"""Hand-eye accuracy on the MuJoCo twin: the full procedure (gated views, executor, rendering at 1280x720, ChArUco
detection, OpenCV methods + reprojection refinement) against the simulation's true extrinsics, for both modes
over several pose-set seeds.

    python bench/handeye.py [--quick] --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

# bench/motion.py would shadow the motion package for scripts run from this folder
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from calibration.board import load_board  # noqa: E402
from calibration.mover import GatedMover  # noqa: E402
from calibration.session import (  # noqa: E402
    ViewCollector,
    board_as_held_object,
    judge,
    nominal_geometry,
    plan_views,
)
from drivers.sim import SimArm, SimCamera, SimWorld, SteppedClock  # noqa: E402
from motion.executor import ExecutorConfig  # noqa: E402
from motion.limits import MotionLimits  # noqa: E402
from runtime.commands.calibrate import pose_error, sim_overrides  # noqa: E402
from runtime.config import load_profile  # noqa: E402
from safety.collision import CollisionWorld  # noqa: E402
from safety.robot_model import RobotModel  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TARGETS = {"max_error_mm": 2.0, "max_error_deg": 0.2}


def calibrate_once(mode: str, seed: int, views: int, texture_dir: Path) -> dict:
    board = load_board(ROOT / "configs/boards/charuco_8x6_30mm.yaml")
    overrides = {
        "sim": {"realtime": False},
        "calibration": {"hand_eye": {"poses": views, "min_views": 6, "seed": seed}},
    }
    base = load_profile(ROOT / "configs/sim.yaml", overrides)
    cfg = base.calibration.hand_eye
    geometry = nominal_geometry(mode, board, cfg, base.camera.sim)
    extra = sim_overrides(mode, board, geometry, texture_dir)
    profile = load_profile(
        ROOT / "configs/sim.yaml", {**overrides, "camera": extra["camera"], "sim": {**overrides["sim"], **extra["sim"]}}
    )
    world = SimWorld(profile.sim, profile.camera)
    arm, camera = SimArm(world), SimCamera(world)
    safety_world = CollisionWorld(RobotModel(world.spec), profile.safety)
    if mode == "eye_to_hand":
        safety_world.set_held_object(board_as_held_object(board, geometry, safety_world))
    t0 = time.perf_counter()
    with arm, camera:
        mover = GatedMover(
            arm,
            safety_world,
            ExecutorConfig.from_configs(profile.robot, profile.safety),
            MotionLimits.from_config(profile.safety, world.spec),
            0.8,
            SteppedClock(world),
        )
        plan = plan_views(mode, board, cfg, geometry, mover, arm.read_state().q)
        A, observations = ViewCollector(mover, camera, board, cfg.settle_s, log=lambda s: None).collect(plan)
        outcome = judge(mode, A, observations, camera.intrinsics.K, board, cfg)
        truth = world.T_world_camera if mode == "eye_to_hand" else world.T_flange_camera
    mm, deg = pose_error(outcome.result.best.X, truth)
    return {
        "mode": mode,
        "seed": seed,
        "views": outcome.views,
        "method": outcome.result.best.method,
        "error_mm": mm,
        "error_deg": deg,
        "residual_mm": outcome.result.median_mm,
        "residual_deg": outcome.result.median_deg,
        "seconds": time.perf_counter() - t0,
        "problems": outcome.problems,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="one seed per mode, 10 views")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    seeds, views = ([0], 10) if args.quick else ([0, 1, 2, 3], 18)
    with tempfile.TemporaryDirectory() as tmp:
        runs = [calibrate_once(m, s, views, Path(tmp)) for m in ("eye_to_hand", "eye_in_hand") for s in seeds]
    result = {
        "runs": runs,
        "max_error_mm": max(r["error_mm"] for r in runs),
        "max_error_deg": max(r["error_deg"] for r in runs),
        "median_error_mm": float(np.median([r["error_mm"] for r in runs])),
        "median_error_deg": float(np.median([r["error_deg"] for r in runs])),
        "render": "1280x720",
        "targets": TARGETS,
    }
    result["met"] = {k: result[k] <= bound for k, bound in TARGETS.items()}
    table = Table(title="hand-eye on the sim (error vs ground truth)")
    for column in ("mode", "seed", "views", "method", "error mm", "error deg", "residual mm", "s"):
        table.add_column(column, justify="right")
    for r in runs:
        table.add_row(
            r["mode"],
            str(r["seed"]),
            str(r["views"]),
            r["method"],
            f"{r['error_mm']:.3f}",
            f"{r['error_deg']:.4f}",
            f"{r['residual_mm']:.3f}",
            f"{r['seconds']:.1f}",
        )
    console = Console()
    console.print(table)
    console.print(
        f"max error {result['max_error_mm']:.3f} mm / {result['max_error_deg']:.4f} deg; met: {result['met']}"
    )
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
