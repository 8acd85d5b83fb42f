"""A point-cloud obstacle from one camera frame: everything the camera sees except the robot itself, the object
the robot is about to touch, and the table top (the table is its own, exact obstacle).

Without these removals the arm would collide with its own image and could never reach the target. The target
mask is dilated a few pixels because depth at object edges smears onto the background.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation

from drivers.types import RGBDFrame
from safety.config import BoxRegion
from safety.geometry import robot_primitives, transform_points
from safety.robot_model import RobotModel


def remove_robot_points(
    points: np.ndarray, robot: RobotModel, q: np.ndarray, gripper_width_m: float | None = None, margin_m: float = 0.02
) -> np.ndarray:
    """Points (N, 3, base frame) that lie outside every robot primitive grown by margin_m at configuration q."""
    poses = robot.fk(q, gripper_width_m)
    keep = np.ones(len(points), dtype=bool)
    for prim in robot_primitives(robot.spec):
        T_base_geom = poses[prim.link] @ prim.T_link_geom
        T_geom_base = np.linalg.inv(T_base_geom)
        idx = np.flatnonzero(keep)
        inside = prim.padded(margin_m).contains(transform_points(T_geom_base, points[idx]))
        keep[idx[inside]] = False
    return points[keep]


def voxel_downsample(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """One point (the centroid) per occupied voxel."""
    if len(points) == 0:
        return points.reshape(0, 3)
    keys = np.floor(points / voxel_m).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse.reshape(-1), points)
    return sums / counts[:, None]


def cloud_from_frame(
    frame: RGBDFrame,
    robot: RobotModel,
    q: np.ndarray,
    *,
    exclude_mask: np.ndarray | None = None,
    gripper_width_m: float | None = None,
    crop: BoxRegion | None = None,
    robot_margin_m: float = 0.02,
    mask_dilation_px: int = 3,
    table_clearance_m: float = 0.01,
    voxel_m: float = 0.01,
) -> np.ndarray:
    """Obstacle points (M, 3) in the base frame from a frame with T_base_camera set.

    exclude_mask: HxW bool of the target object (and anything else the robot may touch), dilated by
    mask_dilation_px. Points within table_clearance_m of the table top, outside `crop` (e.g. the workspace), or
    inside the robot at q (primitives grown by robot_margin_m) are dropped; the rest is voxel-downsampled."""
    if frame.T_base_camera is None:
        raise ValueError("cloud_from_frame needs frame.T_base_camera (attach the hand-eye calibration first)")
    valid = np.isfinite(frame.depth)
    if exclude_mask is not None:
        if exclude_mask.shape != frame.depth.shape:
            raise ValueError(f"exclude_mask shape {exclude_mask.shape} does not match depth {frame.depth.shape}")
        grown = binary_dilation(exclude_mask, iterations=mask_dilation_px) if mask_dilation_px else exclude_mask
        valid &= ~grown
    points = transform_points(frame.T_base_camera, frame.intrinsics.unproject_depth_image(frame.depth)[valid])
    keep = points[:, 2] > table_clearance_m
    if crop is not None:
        keep &= np.all((points >= crop.min_m) & (points <= crop.max_m), axis=1)
    points = voxel_downsample(points[keep], voxel_m)
    return remove_robot_points(points, robot, q, gripper_width_m, robot_margin_m)
