"""Laying a flat object on its face with a parallel gripper: let it go standing on an edge, and let it tip over.

A plate is grasped across its thickness at its rim, so lying flat at its goal it would have one finger under it,
below the table: the gripper cannot set it down there. Instead it is let go standing on the rim point opposite the
grasp, leaning LEAN_DEG past upright towards the grasp side, just above the table: it lands on that edge and falls
about it onto its face, where the goal has it (the rim point it stood on stays where the goal puts it). The
gripper is then nearly upright, as it was taking the plate out of a rack, and the plate hangs below it on the way.
"""

from __future__ import annotations

import math

import numpy as np

from safety.geometry import turn_about

LEAN_DEG = 20.0  # off upright, towards the side it is to fall to (it falls that way, not back)
FLAT_RATIO = 0.25  # a cloud whose thinnest extent is below this share of the next is flat (a plate seen: 0.06; the seen
# half of a can or a cup: 0.4)
LYING_COS = 0.9  # ... and lies on its face when that thinnest direction is this close to vertical
SIDEWAYS_COS = math.cos(math.radians(45.0))  # a gripper whose approach is further than this from down holds it sideways


def flat_normal(points: np.ndarray) -> np.ndarray | None:
    """The normal of a flat object's faces (its cloud's thinnest direction), None when it is not flat."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 3:
        return None
    _, sv, vt = np.linalg.svd(pts - pts.mean(axis=0), full_matrices=False)
    return vt[2] if sv[2] < FLAT_RATIO * sv[1] else None


def tip_turn(T_goal_tcp: np.ndarray, moved_points: np.ndarray) -> np.ndarray | None:
    """The turn (4x4, base frame) that stands the object, lying on its face at its goal (moved_points), up on the
    edge opposite the grasp at T_goal_tcp, on the table (z = 0), leaning LEAN_DEG towards the grasp; None when the
    gripper can set it down as it lies (the gripper at the goal is not sideways, or the object is not flat and
    lying)."""
    if -T_goal_tcp[2, 2] > SIDEWAYS_COS:
        return None
    pts = np.asarray(moved_points, dtype=np.float64).reshape(-1, 3)
    centre = pts.mean(axis=0)
    normal = flat_normal(pts)
    if normal is None or abs(normal[2]) < LYING_COS:
        return None
    towards = T_goal_tcp[:2, 3] - centre[:2]  # from the middle to the grasp, on the table
    if np.linalg.norm(towards) < 1e-3:
        return None
    towards /= np.linalg.norm(towards)
    behind = -float(((pts[:, :2] - centre[:2]) @ towards).min())  # how far the far edge is from the middle
    edge = np.array([*(centre[:2] - behind * towards), float(pts[:, 2].min())])
    axis = np.array([towards[1], -towards[0], 0.0])  # turning about it by +angle raises the grasp side
    T = turn_about(edge, axis, math.radians(90.0 - LEAN_DEG))
    T[2, 3] -= edge[2]  # the edge on the table: lying, the object's height is the table's, not the grounded goal's
    return T
