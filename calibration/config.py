"""Where the hand-eye calibration lives, how old it may be, and how `goalvla calibrate hand-eye` collects views."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from drivers.config import Position, StrictModel, Vec3


class HandEyePlanConfig(StrictModel):
    """The pose set and the quality bar. Nominal mounts only aim the views; the solve measures the true ones."""

    poses: int = Field(default=18, ge=6, le=60, description="views to collect")
    min_views: int = Field(default=12, ge=3, description="views with the board detected needed for a solve")
    max_residual_mm: float = Field(default=3.0, gt=0, description="refuse when the median view residual is larger")
    max_residual_deg: float = Field(default=0.5, gt=0)
    min_rotation_spread_deg: float = Field(default=8.0, ge=0, description="second principal rotation spread")
    target_centre_m: Position = Field(default=(0.45, 0.0, 0.35), description="eye-to-hand: where the board is shown")
    spread_m: float = Field(default=0.10, ge=0, le=0.3, description="eye-to-hand: +- spread of the board centre")
    tilt_deg: float = Field(default=30.0, ge=5, le=60, description="largest tilt away from facing the camera")
    camera_position_m: Position | None = Field(
        default=None, description="eye-to-hand: rough camera position to face the board to (None: sim camera)"
    )
    board_on_flange_xyz_m: Vec3 = Field(default=(0.12, 0.0, 0.10), description="eye-to-hand: board centre, flange")
    board_on_flange_rpy_rad: Vec3 = Field(
        default=(-0.9273, 0.0, 1.5708),
        description="eye-to-hand: board frame in the flange frame; default: a plate on the gripper's +x side whose "
        "printed face looks along flange (0.8, 0, -0.6), i.e. at a camera in front of and above the robot",
    )
    board_on_table_m: Position = Field(
        default=(0.35, -0.35, 0.004), description="eye-in-hand: board centre on the table"
    )
    flange_camera_xyz_m: Vec3 | None = Field(default=None, description="eye-in-hand: nominal camera mount (None: sim)")
    flange_camera_rpy_rad: Vec3 | None = None
    standoff_m: float = Field(default=0.45, gt=0.2, lt=1.0, description="eye-in-hand: camera-to-board distance")
    settle_s: float = Field(default=0.5, ge=0, le=10, description="wait after each move before the picture")
    speed_fraction: float = Field(default=0.3, gt=0, le=1.0, description="of safety.max_joint_velocity_rad_s")
    seed: int = Field(default=0, ge=0, lt=2**63)


class CalibrationConfig(StrictModel):
    mode: Literal["eye_to_hand", "eye_in_hand"] = "eye_to_hand"
    file: Path | None = Field(
        default=None, description="calibration YAML; None on the sim = the simulated camera's true pose"
    )
    max_age_days: float = Field(default=30.0, gt=0, le=3650, description="older calibrations raise a warning")
    hand_eye: HandEyePlanConfig = HandEyePlanConfig()
