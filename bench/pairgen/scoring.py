"""Errors of an estimated motion against the truth. Rotation is taken modulo the symmetry the generator knows as
truth (the turns the goal view cannot show), so a method is not blamed for a turn no image can reveal, and it
cannot hide an error behind a symmetry the object does not have.

A method that reports a symmetry with its motion (ours) is scored modulo what it reports too, but never beyond
the shape's own symmetry (reported_rotation_error_deg): a turn only the print could show may be reported as unseen,
a turn the shape shows may not.

Rotation error = the angle of E = R_true^T R_est (acting on the object as first seen, camera frame) after the true
symmetry's turns are taken out; translation error = distance between where the two motions put the object's centre.
"""

from __future__ import annotations

import math

import numpy as np

from bench.pairgen.generate import TrueSymmetry


def _angle(R: np.ndarray) -> float:
    return math.degrees(math.acos(float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


def translation_error_mm(R_est, t_est, T_true: np.ndarray, centre: np.ndarray) -> float:
    return 1000.0 * float(np.linalg.norm((R_est @ centre + t_est) - (T_true[:3, :3] @ centre + T_true[:3, 3])))


def rotation_error_deg(R_est: np.ndarray, R_true: np.ndarray, R_obj0: np.ndarray, truth: TrueSymmetry) -> float:
    """Angle [deg] left after the turns of `truth` (object frame; R_obj0 is the object's initial orientation in the
    camera frame) are taken out. NaN for a true ball: no rotation is observable."""
    if truth.ball:
        return float("nan")
    E = R_true.T @ R_est
    if truth.axis is not None:  # a body of revolution: only where its axis points counts (end for end too if flip)
        axis = R_obj0 @ truth.axis
        c = float(axis @ E @ axis)
        if truth.flip:
            c = abs(c)
        return math.degrees(math.acos(np.clip(c, -1.0, 1.0)))
    elems = np.einsum("ij,kjl,ml->kim", R_obj0, truth.rotations, R_obj0)
    return min(_angle(G.T @ E) for G in elems)


def reported_rotation_error_deg(
    R_est: np.ndarray,
    R_true: np.ndarray,
    R_obj0: np.ndarray,
    truth: TrueSymmetry,
    shape: TrueSymmetry,
    reported: TrueSymmetry | None,
) -> float:
    """The rotation error modulo the true symmetry, or modulo the reported one (object frame) where that is
    smaller but never below the error modulo the shape's own symmetry. NaN when the truth is a ball (no turn shows)."""
    true_error = rotation_error_deg(R_est, R_true, R_obj0, truth)
    if reported is None or not math.isfinite(true_error):
        return true_error
    shape_error = rotation_error_deg(R_est, R_true, R_obj0, shape)  # NaN: a ball, no turn shows by shape
    mod_reported = rotation_error_deg(R_est, R_true, R_obj0, reported)  # NaN: a ball reported
    shape_error = shape_error if math.isfinite(shape_error) else 0.0
    mod_reported = mod_reported if math.isfinite(mod_reported) else 0.0
    return min(true_error, max(shape_error, mod_reported))
