"""The clouds contact planning needs, from one capture: the target's points and everything else, base frame."""

from __future__ import annotations

import numpy as np

from drivers.types import RGBDFrame
from safety.geometry import transform_points
from safety.pointcloud import cloud_from_frame
from safety.robot_model import RobotModel


def target_and_scene(
    frame: RGBDFrame, mask: np.ndarray, robot: RobotModel, q: np.ndarray, voxel_m: float = 0.005
) -> tuple[np.ndarray, np.ndarray]:
    """(target points (N, 3), scene points without the target, the robot or the table top), base frame.

    The frame must carry T_base_camera; q is the arm's configuration at capture (to cut the robot out).
    """
    if frame.T_base_camera is None:
        raise ValueError("target_and_scene: the frame has no T_base_camera (attach the hand-eye calibration)")
    if mask.shape != frame.depth.shape or mask.dtype != np.bool_:
        raise ValueError(f"target mask must be bool {frame.depth.shape}, got {mask.dtype} {mask.shape}")
    pts = frame.intrinsics.unproject_depth_image(frame.depth)[mask]
    target = transform_points(frame.T_base_camera, pts[np.all(np.isfinite(pts), axis=1)])
    scene = cloud_from_frame(frame, robot, q, exclude_mask=mask, voxel_m=voxel_m)
    return target, scene
