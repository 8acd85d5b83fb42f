"""The clouds contact planning and the manipulation need, built once from one capture, base frame.

The target's points come from the reasoning stage's mask. The scene is everything else the camera saw, as the
gate's obstacle: without the robot, the table top and the target, cropped to the workspace, and cleaned of two
kinds of points that are not obstacles. The open gripper's gap is no robot primitive, so the camera's points of
the inner finger faces survive robot removal and would hang in the air where the hand was: the region around the
TCP goes. And depth smears the target's edges beyond its mask: points next to the target's own points go too, or
the carry would collide with a ghost of the object where it used to stand.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from drivers.types import RGBDFrame
from safety.config import BoxRegion
from safety.geometry import transform_points
from safety.pointcloud import cloud_from_frame
from safety.robot_model import RobotModel

HAND_REGION_M = 0.07  # radius about the TCP at capture time whose points belong to the hand
TARGET_MARGIN_M = 0.015  # scene points this close to the target's own points are the target's


@dataclass(frozen=True)
class SceneClouds:
    target: np.ndarray  # (N, 3) the target's seen points
    scene: np.ndarray  # (M, 3) the obstacle points: no robot, hand, table top or target


def scene_clouds(
    frame: RGBDFrame,
    target_mask: np.ndarray,
    robot: RobotModel,
    q: np.ndarray,
    *,
    workspace: BoxRegion | None = None,
    voxel_m: float = 0.01,
) -> SceneClouds:
    """The target's and the scene's points of one capture; q is the arm's configuration at the capture."""
    if frame.T_base_camera is None:
        raise ValueError("scene_clouds: the frame has no T_base_camera (attach the hand-eye calibration)")
    if target_mask.shape != frame.depth.shape or target_mask.dtype != np.bool_:
        raise ValueError(f"target mask must be bool {frame.depth.shape}, got {target_mask.dtype} {target_mask.shape}")
    valid = target_mask & np.isfinite(frame.depth)
    target = transform_points(frame.T_base_camera, frame.intrinsics.unproject_depth_image(frame.depth)[valid])
    scene = cloud_from_frame(frame, robot, q, exclude_mask=target_mask, crop=workspace, voxel_m=voxel_m)
    scene = scene[np.linalg.norm(scene - robot.tcp_pose(q)[:3, 3], axis=1) > HAND_REGION_M]
    if len(target) and len(scene):
        near, _ = cKDTree(target).query(scene, distance_upper_bound=TARGET_MARGIN_M)
        scene = scene[~np.isfinite(near)]
    return SceneClouds(target, scene)
