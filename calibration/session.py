"""`goalvla calibrate hand-eye`: plan safe views, drive the arm through them, detect the board, solve, judge.

Every move is a minimum-jerk joint path from the measured position, approved by the safety gate (limits, speeds,
per-tick step, workspace, self and scene collision with the board as a held object) and streamed by the motion
executor; a refused or interrupted move stops the procedure. The arm's measured joints (after settling) give
T_base_flange, so the stored result does not depend on the controller's TCP settings. Nothing here prompts: the
caller confirms the plan (UI lives in the runtime).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from calibration.board import CharucoBoardSpec
from calibration.config import HandEyePlanConfig
from calibration.detect import BoardDetector, BoardObservation
from calibration.handeye import HandEyeResult, Mode, rotation_diversity_deg, solve_hand_eye
from calibration.mover import CalibrationRefused, GatedMover, reachable_views
from calibration.poses import PosePlan, board_centre, eye_in_hand_targets, eye_to_hand_targets, solve_poses
from calibration.store import HandEyeCalibration
from drivers.interfaces import Camera
from safety.collision import CollisionWorld
from safety.gate import check_configuration
from safety.geometry import Primitive

CANDIDATES_PER_VIEW = 4  # random targets tried per wanted view (many fail IK or collide)


@dataclass(frozen=True)
class Geometry:
    """Nominal geometry used to aim the views (the solve measures the real one)."""

    T_flange_board: np.ndarray | None = None  # eye-to-hand
    camera_position: np.ndarray | None = None  # eye-to-hand
    T_base_board: np.ndarray | None = None  # eye-in-hand
    T_flange_camera: np.ndarray | None = None  # eye-in-hand


@dataclass(frozen=True)
class HandEyeOutcome:
    result: HandEyeResult
    calibration: HandEyeCalibration
    views: int
    rotation_spread_deg: float
    problems: list[str]  # empty: good enough to store


def nominal_geometry(mode: Mode, board: CharucoBoardSpec, cfg: HandEyePlanConfig, sim_camera=None) -> Geometry:
    """Board on the flange as configured, or flat on the table face-up (board z = -base z).
    `sim_camera` (SimCameraConfig) supplies the camera guesses the plan config leaves unset."""
    flip = np.diag([1.0, -1.0, -1.0])
    if mode == "eye_to_hand":
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("xyz", cfg.board_on_flange_rpy_rad).as_matrix()
        T[:3, 3] = np.asarray(cfg.board_on_flange_xyz_m) - T[:3, :3] @ board_centre(board)
        position = cfg.camera_position_m or (sim_camera.position_m if sim_camera is not None else None)
        if position is None:
            raise CalibrationRefused("calibration.hand_eye.camera_position_m is needed to aim the views")
        return Geometry(T_flange_board=T, camera_position=np.asarray(position, dtype=float))
    T = np.eye(4)
    T[:3, :3] = flip
    T[:3, 3] = np.asarray(cfg.board_on_table_m) - flip @ board_centre(board)
    xyz = cfg.flange_camera_xyz_m or (sim_camera.flange_xyz_m if sim_camera is not None else None)
    rpy = cfg.flange_camera_rpy_rad or (sim_camera.flange_rpy_rad if sim_camera is not None else (0.0, 0.0, 0.0))
    if xyz is None:
        raise CalibrationRefused("calibration.hand_eye.flange_camera_xyz_m is needed to aim the views")
    T_fc = np.eye(4)
    T_fc[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()
    T_fc[:3, 3] = xyz
    return Geometry(T_base_board=T, T_flange_camera=T_fc)


def board_as_held_object(board: CharucoBoardSpec, geometry: Geometry, world: CollisionWorld) -> Primitive:
    """The flange-mounted board as a box the gate checks against the robot and the scene."""
    spec = world.robot.spec
    T_flange_tcp = world.robot.frame_pose(world.robot.home_q, spec.flange_link)
    T_flange_tcp = np.linalg.inv(T_flange_tcp) @ world.robot.frame_pose(world.robot.home_q, spec.tcp_link)
    T_board_centre = geometry.T_flange_board.copy()
    T_board_centre[:3, 3] = geometry.T_flange_board[:3, :3] @ board_centre(board) + geometry.T_flange_board[:3, 3]
    w, h = board.size_m
    return Primitive(
        "held:calibration_board", spec.tcp_link, "box", (w, h, 0.006), np.linalg.inv(T_flange_tcp) @ T_board_centre
    )


def plan_views(
    mode: Mode,
    board: CharucoBoardSpec,
    cfg: HandEyePlanConfig,
    geometry: Geometry,
    mover: GatedMover,
    q_start: np.ndarray,
) -> PosePlan:
    """Up to cfg.poses flange poses with IK inside the limits, collision-free, and reachable one after the other
    through gate-approved moves (all checked before anything moves)."""
    rng = np.random.default_rng(cfg.seed)
    n = cfg.poses * CANDIDATES_PER_VIEW
    if mode == "eye_to_hand":
        targets = eye_to_hand_targets(
            board,
            geometry.T_flange_board,
            geometry.camera_position,
            np.asarray(cfg.target_centre_m),
            cfg.spread_m,
            cfg.tilt_deg,
            n,
            rng,
        )
    else:
        targets = eye_in_hand_targets(
            board, geometry.T_base_board, geometry.T_flange_camera, cfg.standoff_m, cfg.tilt_deg, n, rng
        )
    world = mover.world
    robot = world.robot

    def ik(T: np.ndarray, seed: np.ndarray) -> np.ndarray | None:
        result = robot.ik(
            T,
            seed,
            preferred_q=q_start,
            frame=robot.spec.flange_link,
            accept=lambda q: not check_configuration(q, world),
        )
        return result.q if result.success else None

    candidates = solve_poses(targets, ik, q_start, 2 * cfg.poses)
    reachable = reachable_views(candidates, mover, q_start)
    k = cfg.poses
    return PosePlan(reachable.T_base_flange[:k], reachable.q[:k], reachable.rejected)


class ViewCollector:
    """Drives through the plan, captures and detects the board at each view, records the measured flange pose."""

    def __init__(
        self,
        mover: GatedMover,
        camera: Camera,
        board: CharucoBoardSpec,
        settle_s: float,
        log: Callable[[str], None] = print,
    ) -> None:
        self.mover, self.camera = mover, camera
        self.detector = BoardDetector(board, camera.intrinsics)
        self.settle_s = settle_s
        self.log = log

    def collect(self, plan: PosePlan) -> tuple[list[np.ndarray], list[BoardObservation]]:
        arm, robot = self.mover.arm, self.mover.world.robot
        A, views = [], []
        for k, q in enumerate(plan.q, start=1):
            self.mover.move_to(q, self.settle_s)
            frame = self.camera.read()
            q_measured = arm.read_state().q
            observation = self.detector.detect(frame.rgb)
            if observation is None:
                self.log(f"view {k}/{len(plan.q)}: board not found, skipped")
                continue
            A.append(robot.frame_pose(q_measured, robot.spec.flange_link))
            views.append(observation)
            self.log(
                f"view {k}/{len(plan.q)}: {len(observation.image_points)} corners, "
                f"{observation.reprojection_px:.2f} px RMS"
            )
        return A, views


def judge(
    mode: Mode,
    A: list[np.ndarray],
    views: list[BoardObservation],
    K: np.ndarray,
    board: CharucoBoardSpec,
    cfg: HandEyePlanConfig,
) -> HandEyeOutcome:
    """Solve and hold the result against the quality bar (problems listed; empty means store it)."""
    problems = []
    if len(views) < cfg.min_views:
        problems.append(f"only {len(views)} views found the board (need {cfg.min_views})")
    spread = rotation_diversity_deg(A)
    if spread < cfg.min_rotation_spread_deg:
        problems.append(
            f"views rotate too little about a second axis ({spread:.1f} deg < "
            f"{cfg.min_rotation_spread_deg} deg): widen tilt_deg"
        )
    result = solve_hand_eye(mode, A, views, K, board_centre(board))
    if result.median_mm > cfg.max_residual_mm:
        problems.append(f"median view residual {result.median_mm:.2f} mm > {cfg.max_residual_mm} mm")
    if result.median_deg > cfg.max_residual_deg:
        problems.append(f"median view residual {result.median_deg:.3f} deg > {cfg.max_residual_deg} deg")
    calibration = HandEyeCalibration(
        mode=mode,
        T=tuple(tuple(float(v) for v in row) for row in result.best.X),
        created=dt.datetime.now(dt.UTC),
        method=result.best.method,
        poses=len(views),
        residual_mm=result.median_mm,
        residual_deg=result.median_deg,
    )
    return HandEyeOutcome(result, calibration, len(views), spread, problems)
