"""Verification: capture again, measure how the target really moved, and compare it with the goal's motion.

Both motions are measured the same way (the grounding stage's registration, here between the initial capture
and the new one, both metric) and compared where it matters: the object's centre, moved by each. Rotation is
judged only when the goal asked for one (>= ROTATION_INTENDED_DEG), since the yaw of a symmetric object or a
placed block is otherwise free; it is always reported.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from runtime.context import Verification

ROTATION_INTENDED_DEG = 10.0


def rotation_deg(R: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(R).magnitude()))


def object_centre(points_camera: np.ndarray) -> np.ndarray:
    """Centre of the visible object points (N, 3) in the camera frame, robust to stray edge pixels."""
    return np.median(points_camera, axis=0)


def compare(
    goal_R: np.ndarray,
    goal_t: np.ndarray,
    achieved_R: np.ndarray,
    achieved_t: np.ndarray,
    centre_camera: np.ndarray,
    position_tol_m: float,
    rotation_tol_deg: float,
) -> Verification:
    """Verdict from the goal and achieved motions (x' = R x + t, camera frame) of an object centred at centre."""
    p_goal = goal_R @ centre_camera + goal_t
    p_achieved = achieved_R @ centre_camera + achieved_t
    position_error = float(np.linalg.norm(p_goal - p_achieved))
    rotation_error = rotation_deg(goal_R.T @ achieved_R)
    goal_rotation = rotation_deg(goal_R)
    judged_rotation = goal_rotation >= ROTATION_INTENDED_DEG
    details = {
        "goal_translation_m": float(np.linalg.norm(p_goal - centre_camera)),
        "achieved_translation_m": float(np.linalg.norm(p_achieved - centre_camera)),
        "goal_rotation_deg": goal_rotation,
        "achieved_rotation_deg": rotation_deg(achieved_R),
        "rotation_judged": judged_rotation,
        "position_tol_m": position_tol_m,
        "rotation_tol_deg": rotation_tol_deg,
    }
    problems = []
    if position_error > position_tol_m:
        problems.append(
            f"object centre {position_error * 1000:.0f} mm from the goal (tolerance {position_tol_m * 1000:.0f})"
        )
    if judged_rotation and rotation_error > rotation_tol_deg:
        problems.append(f"object rotation {rotation_error:.1f} deg off the goal (tolerance {rotation_tol_deg:.0f})")
    reason = "; ".join(problems) or (
        f"goal reached: centre within {position_error * 1000:.0f} mm, rotation within {rotation_error:.1f} deg"
    )
    return Verification(not problems, reason, position_error, rotation_error, details)
