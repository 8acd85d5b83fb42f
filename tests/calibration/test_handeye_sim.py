"""Hand-eye calibration end to end on the MuJoCo twin: plan gated views, drive the simulated arm, render the
ChArUco board (on the gripper for eye-to-hand, on the table with a flange camera for eye-in-hand), solve, and
compare with the simulation's true extrinsics: within 2 mm and 0.2 deg.

Rendered at 1280x720 (the Femto Bolt colour mode the lab profile uses): at the default 640x360 a 30 mm square
spans ~13 px at 0.8 m and per-view PnP noise grows accordingly.
"""

from __future__ import annotations

import numpy as np
import pytest

from calibration.board import load_board
from calibration.mover import GatedMover
from calibration.session import (
    ViewCollector,
    board_as_held_object,
    judge,
    nominal_geometry,
    plan_views,
)
from drivers.sim import SimArm, SimCamera, SimWorld, SteppedClock
from motion.executor import ExecutorConfig
from motion.limits import MotionLimits
from runtime.commands.calibrate import pose_error, sim_overrides
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

BOARD = "configs/boards/charuco_8x6_30mm.yaml"
N_VIEWS = 12


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["eye_to_hand", "eye_in_hand"])
def test_recovers_true_extrinsics(sim_profile_with, tmp_path, mode):
    board = load_board(BOARD)
    base = sim_profile_with()
    plan_cfg = base.calibration.hand_eye.model_copy(update={"poses": N_VIEWS, "min_views": 10})
    geometry = nominal_geometry(mode, board, plan_cfg, base.camera.sim)
    profile = sim_profile_with(sim_overrides(mode, board, geometry, tmp_path))  # board placed, 1280x720
    world = SimWorld(profile.sim, profile.camera)
    arm, camera = SimArm(world), SimCamera(world)
    safety_world = CollisionWorld(RobotModel(world.spec), profile.safety)
    if mode == "eye_to_hand":
        safety_world.set_held_object(board_as_held_object(board, geometry, safety_world))
    with arm, camera:
        config = ExecutorConfig.from_configs(profile.robot, profile.safety)
        limits = MotionLimits.from_config(profile.safety, world.spec)
        mover = GatedMover(arm, safety_world, config, limits, 0.8, SteppedClock(world))
        plan = plan_views(mode, board, plan_cfg, geometry, mover, arm.read_state().q)
        assert len(plan.q) == N_VIEWS
        A, views = ViewCollector(mover, camera, board, plan_cfg.settle_s, log=lambda s: None).collect(plan)
        outcome = judge(mode, A, views, camera.intrinsics.K, board, plan_cfg)
        truth = world.T_world_camera if mode == "eye_to_hand" else world.T_flange_camera
    err_mm, err_deg = pose_error(outcome.result.best.X, truth)
    print(
        f"{mode}: {outcome.views} views, method {outcome.result.best.method}, error {err_mm:.3f} mm "
        f"{err_deg:.4f} deg, median residual {outcome.result.median_mm:.3f} mm {outcome.result.median_deg:.4f} deg"
    )
    assert outcome.problems == []
    assert err_mm < 2.0 and err_deg < 0.2
    assert outcome.calibration.mode == mode and outcome.calibration.poses == outcome.views
    assert np.allclose(outcome.calibration.matrix, outcome.result.best.X)
