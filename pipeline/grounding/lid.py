"""Whether a lid lies shut: the tilt of its seen face from the table's plane.

Closing asks for a lid shut on its box, which is a lid lying flat over it. The goal motion of a hinged part is an
estimate (its hinge and angle grounded from an edited image, a few degrees off), so an achieved turn within the
rotation tolerance of that goal can leave the lid as far open as the tolerance plus the goal's own error (a lid
left 17 deg open was measured 9 deg off a grounded goal that itself stopped 7 deg short of shut). The lid's seen
face says directly whether it is shut: the plane fitted to its points in the base frame (z up, the table's
normal), with points off the face (its front edge, pixels mixed with the box or the table) left out.
"""

from __future__ import annotations

import math

import numpy as np

MIN_POINTS = 30  # fewer seen points of the lid than this measure no plane
INLIER_M = 0.003  # a point this close to a plane lies on it
TRIALS = 200  # RANSAC planes through three points; the one most points lie on is refitted to them
MIN_SHARE = 0.5  # ... and it must hold this share of them: the face is most of what the lid's mask sees


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
