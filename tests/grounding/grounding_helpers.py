"""Helpers for the grounding tests: goal poses and error measures on simulated pairs."""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation


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
