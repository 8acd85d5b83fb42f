"""Helpers for the grounding tests: goal poses and error measures on simulated pairs, and raycast pairs grounded."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # bench/ is not an installed package


def goal_pose(renderer, name: str, shift_xy, yaw_deg: float, tilt_deg: float = 0.0) -> np.ndarray:
    """Object pose after turning about its centre (tilt about base x, then yaw) and shifting on the table."""
    T0 = renderer.world.object_pose(name)
    c = renderer._centre(name)
    R = (Rotation.from_euler("z", yaw_deg, degrees=True) * Rotation.from_euler("x", tilt_deg, degrees=True)).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R @ T0[:3, :3]
    T[:3, 3] = R @ (T0[:3, 3] - c) + c + np.array([shift_xy[0], shift_xy[1], 0.0])
    return T


def errors(pair, motion) -> tuple[float, float, float]:
    """(centre translation error [mm], rotation error [deg], axis error [deg] for the object's z axis)."""
    M, c = pair.T_motion_camera, pair.centre_camera
    t_err = 1000 * np.linalg.norm((motion.R @ c + motion.t) - (M[:3, :3] @ c + M[:3, 3]))
    r_err = math.degrees(Rotation.from_matrix(motion.R.T @ M[:3, :3]).magnitude())
    axis = pair.T_camera_object0[:3, 2]
    a_err = math.degrees(math.acos(np.clip(np.dot(motion.R @ axis, M[:3, :3] @ axis), -1, 1)))
    return t_err, r_err, a_err


def grounded_raycast(seed: int, index: int):
    """(the pair, ground()'s accepted motion) of raycast pair `index` of set `seed` (bench.pairgen)."""
    from bench.pairgen.generate import make_pair
    from pipeline.grounding.ground import ground
    from pipeline.grounding.types import GroundingConfig, GroundingInput
    from pipeline.perception.offline_features import OfflineFeatures

    p = make_pair(seed, index)
    inp = GroundingInput(p.rgb0, p.depth0, p.mask0, p.rgb1, p.depth1, p.depth1_kind, p.mask1, p.intrinsics)
    motion = ground(inp, OfflineFeatures(), GroundingConfig(), T_base_camera=p.T_base_camera)
    assert motion.ok, motion.reason
    return p, motion


def hull_mask(K, points: np.ndarray, grow_px: int = 0) -> np.ndarray:
    """(H, W) the filled convex hull of the camera-frame points' images (to a sixteenth of a pixel), grown by grow_px
    all round (shrunk where negative), as a segmenter's mask of a convex body."""
    hull = cv2.convexHull(K.project(points).astype(np.float32))
    mask = np.zeros((K.height, K.width), np.uint8)
    cv2.fillConvexPoly(mask, np.round(hull * 16).astype(np.int32), 1, shift=4)
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * abs(grow_px) + 1,) * 2)
    return (cv2.dilate(mask, disc) if grow_px >= 0 else cv2.erode(mask, disc)).astype(bool)
