"""Verification: capture again, measure how the target really moved, and compare it with the goal's motion.

Both motions are measured the same way (the grounding stage's registration, here between the initial capture
and the new one, both metric) and compared where it matters: the object's centre, moved by each. The rotation
difference is split, in the base frame, into tilt (how far the object's vertical axis is off) and twist (turn
about the vertical), and each is judged only when the goal itself asks for that kind of rotation (at least
INTENDED_DEG): the registration of a symmetric object (a cube, a cylinder) is free to pick any of its symmetric
poses, so an unasked rotation is reported, never judged. A body of revolution about the vertical (a ball, an
upright can) has no visible twist at all, so its twist is never judged and its position is compared on its axis
(the centroid of the seen side swings with that invisible twist); it is recognised from the initial points, which
then lie on one surface of revolution about some vertical axis (each height slice a circle about it).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from runtime.context import Verification

INTENDED_DEG = 10.0
REVOLUTION_SLICE_M = 0.005
REVOLUTION_TOL_REL = 0.02  # median distance off the fitted surface / object size (balls ~0.014, boxes >= 0.03)


def rotation_deg(R: np.ndarray) -> float:
    return float(np.degrees(Rotation.from_matrix(R).magnitude()))


def twist_tilt_deg(R_base: np.ndarray) -> tuple[float, float]:
    """(turn about the base z axis, tilt of the z axis) of a rotation in the base frame, degrees."""
    _, _, z, w = Rotation.from_matrix(R_base).as_quat()
    twist = abs(math.degrees(2 * math.atan2(z, w)))
    twist = 360.0 - twist if twist > 180.0 else twist
    tilt = math.degrees(math.acos(float(np.clip(R_base[2, 2], -1.0, 1.0))))
    return twist, tilt


def revolution_axis(points_base: np.ndarray) -> np.ndarray | None:
    """The point on the vertical axis the object's points (N, 3, base frame) revolve about, at their median height,
    or None when they do not lie on a surface of revolution about a vertical axis."""
    P = np.asarray(points_base, dtype=np.float64)
    size = float(np.linalg.norm(np.ptp(P, axis=0))) if len(P) else 0.0
    if len(P) < 20 or size <= 0.0:
        return None
    slices = np.floor((P[:, 2] - P[:, 2].min()) / REVOLUTION_SLICE_M).astype(int)
    labels, slice_of = np.unique(slices, return_inverse=True)
    # every slice a circle about (x0, y0) with its own radius: x^2 + y^2 = 2 x0 x + 2 y0 y + c_slice
    A = np.zeros((len(P), 2 + len(labels)))
    A[:, :2] = 2 * P[:, :2]
    A[np.arange(len(P)), 2 + slice_of] = 1.0
    x0, y0 = np.linalg.lstsq(A, (P[:, :2] ** 2).sum(axis=1), rcond=None)[0][:2]
    radius = np.hypot(P[:, 0] - x0, P[:, 1] - y0)
    off = np.abs(radius - np.array([np.median(radius[slice_of == k]) for k in range(len(labels))])[slice_of])
    if np.median(off) > REVOLUTION_TOL_REL * size:
        return None
    return np.array([x0, y0, float(np.median(P[:, 2]))])


def object_centre(points_camera: np.ndarray) -> np.ndarray:
    """Centre of the visible object points (N, 3) in the camera frame, robust to stray edge pixels."""
    return np.median(points_camera, axis=0)


def compare(
    goal_R: np.ndarray,
    goal_t: np.ndarray,
    achieved_R: np.ndarray,
    achieved_t: np.ndarray,
    centre_camera: np.ndarray,
    R_base_camera: np.ndarray,
    position_tol_m: float,
    rotation_tol_deg: float,
    twist_visible: bool = True,
) -> Verification:
    """Verdict from the goal and achieved motions (x' = R x + t, camera frame) of an object centred at centre;
    `twist_visible` False for a body of revolution about the vertical (its twist is not judged)."""
    p_goal = goal_R @ centre_camera + goal_t
    p_achieved = achieved_R @ centre_camera + achieved_t
    position_error = float(np.linalg.norm(p_goal - p_achieved))
    to_base = lambda R: R_base_camera @ R @ R_base_camera.T  # noqa: E731
    goal_twist, goal_tilt = twist_tilt_deg(to_base(goal_R))
    twist_error, tilt_error = twist_tilt_deg(to_base(goal_R.T @ achieved_R))
    judge_twist, judge_tilt = twist_visible and goal_twist >= INTENDED_DEG, goal_tilt >= INTENDED_DEG
    details = {
        "goal_translation_m": float(np.linalg.norm(p_goal - centre_camera)),
        "achieved_translation_m": float(np.linalg.norm(p_achieved - centre_camera)),
        "goal_twist_deg": goal_twist,
        "goal_tilt_deg": goal_tilt,
        "twist_error_deg": twist_error,
        "tilt_error_deg": tilt_error,
        "twist_judged": judge_twist,
        "twist_visible": twist_visible,
        "tilt_judged": judge_tilt,
        "position_tol_m": position_tol_m,
        "rotation_tol_deg": rotation_tol_deg,
    }
    problems = []
    if position_error > position_tol_m:
        problems.append(
            f"object centre {position_error * 1000:.0f} mm from the goal (tolerance {position_tol_m * 1000:.0f})"
        )
    if judge_tilt and tilt_error > rotation_tol_deg:
        problems.append(f"object tilted {tilt_error:.1f} deg off the goal (tolerance {rotation_tol_deg:.0f})")
    if judge_twist and twist_error > rotation_tol_deg:
        problems.append(f"object turned {twist_error:.1f} deg off the goal (tolerance {rotation_tol_deg:.0f})")
    rotation_error = rotation_deg(goal_R.T @ achieved_R)
    reason = "; ".join(problems) or (
        f"goal reached: centre within {position_error * 1000:.0f} mm"
        + (f", tilt within {tilt_error:.1f} deg" if judge_tilt else "")
        + (f", turn within {twist_error:.1f} deg" if judge_twist else "")
    )
    return Verification(not problems, reason, position_error, rotation_error, details)
