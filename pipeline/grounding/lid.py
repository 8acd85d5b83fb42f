"""Whether a lid lies shut: the tilt of its seen face from the table's plane.

Closing asks for a lid shut on its box, which is a lid lying flat over it. The goal motion of a hinged part is an
estimate (its hinge and angle grounded from an edited image, a few degrees off), so an achieved turn within the
rotation tolerance of that goal can leave the lid as far open as the tolerance plus the goal's own error (a lid
left 17 deg open was measured 9 deg off a grounded goal that itself stopped 7 deg short of shut). The lid's seen
face says directly whether it is shut: the plane fitted to its points in the base frame (z up, the table's
normal), with points off the face (its front edge, pixels mixed with the box or the table) left out. Where the lid
lies says whether it is over its box (`over_its_box`), when the achieved motion cannot be trusted to say so (a
lid's seen face is thin and uniform: its registration can land a turn or a flip off).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import Delaunay, QhullError

MIN_POINTS = 30  # fewer seen points of the lid than this measure no plane
INLIER_M = 0.003  # a point this close to a plane lies on it
TRIALS = 200  # RANSAC planes through three points; the one most points lie on is refitted to them
MIN_SHARE = 0.5  # ... and it must hold this share of them: the face is most of what the lid's mask sees
OVER_SHARE = 0.8  # a lid over its box has this share of its seen points above the box's outline
TOP_BAND_M = (-0.02, 0.03)  # ... at a height this near the box's top (its own thickness, a rim)


def face_tilt_deg(points_base: np.ndarray) -> float | None:
    """Angle (deg, 0..90) between the plane of the seen face and the table's (base xy) plane; None when fewer
    than MIN_POINTS points are given, they span no plane, or no plane holds MIN_SHARE of them. The face is the
    plane most points lie on (RANSAC, seeded: the same points give the same answer), refitted to those points."""
    P = np.asarray(points_base, dtype=np.float64).reshape(-1, 3)
    P = P[np.isfinite(P).all(axis=1)]
    if len(P) < MIN_POINTS:
        return None
    rng = np.random.default_rng(0)
    best = np.zeros(len(P), bool)
    for a, b, c in rng.integers(0, len(P), size=(TRIALS, 3)):
        n = np.cross(P[b] - P[a], P[c] - P[a])
        norm = np.linalg.norm(n)
        if norm < 1e-9:
            continue
        on = np.abs((P - P[a]) @ (n / norm)) <= INLIER_M
        if on.sum() > best.sum():
            best = on
    if best.sum() < max(MIN_POINTS, MIN_SHARE * len(P)):
        return None
    Q = P[best] - P[best].mean(axis=0)
    _, s, vt = np.linalg.svd(Q, full_matrices=False)
    if s[1] <= 1e-9:  # collinear: no plane
        return None
    return math.degrees(math.acos(min(1.0, abs(float(vt[2][2])))))


def over_its_box(lid_points_base: np.ndarray, box_points_base: np.ndarray) -> bool:
    """Whether a lid's seen points (base frame, after it moved) lie over its box's (before): OVER_SHARE of them
    inside the outline of the box's points seen from above, their median height within TOP_BAND_M of the box's top
    (its 98th percentile). A lid swung off its box, or fallen beside it, is not."""
    L = np.asarray(lid_points_base, dtype=np.float64).reshape(-1, 3)
    B = np.asarray(box_points_base, dtype=np.float64).reshape(-1, 3)
    L, B = L[np.isfinite(L).all(axis=1)], B[np.isfinite(B).all(axis=1)]
    if len(L) < MIN_POINTS or len(B) < MIN_POINTS:
        return False
    try:
        outline = Delaunay(B[:, :2])
    except QhullError:  # the box's points span no area seen from above
        return False
    over = float((outline.find_simplex(L[:, :2]) >= 0).mean())
    height = float(np.median(L[:, 2])) - float(np.percentile(B[:, 2], 98))
    return over >= OVER_SHARE and TOP_BAND_M[0] <= height <= TOP_BAND_M[1]
