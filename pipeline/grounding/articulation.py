"""Articulated parts: a lid turns about the line where it meets the object it belongs to.

A flat, uniformly coloured part (a lid) registers equally well flipped end for end, and the camera sees one face
of it before the turn and the other face after, so neither features nor a one-sided render-and-compare can tell
its motion. What can: the part stays attached. Its points next to the anchor object (the box) give the hinge
line, which leaves one unknown, the angle. The angle is the one whose turned part best covers the goal's
silhouette, and whose goal part turned back best covers the initial silhouette (both ways, so a part that is
partly hidden in one view is still judged by the other); silhouettes do not care which face is seen.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial import cKDTree

from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity
from safety.geometry import turn_about

ATTACH_M = 0.012  # part points this close to the anchor's points are where the two meet
MIN_ATTACH_POINTS = 10
MIN_ELONGATION = 3.0  # the meeting points must form a line, not a blob (a hinge, not a touching corner)
HINGE_EDGE_PERCENTILE = 5  # the hinge is the attached band's edge towards the anchor, not the band's middle
COARSE_STEP_DEG, FINE_STEP_DEG, FINE_SPAN_DEG = 5.0, 0.25, 5.0


class HingeNotFound(ValueError):
    """The part does not meet its anchor along a line; the message says how it falls short."""


@dataclass(frozen=True)
class Hinge:
    """A line in the camera frame: points p + s * axis (axis unit length), and the part points on it."""

    point: np.ndarray
    axis: np.ndarray
    attached: np.ndarray  # (N, 3) part points where it meets the anchor

    def turn(self, angle_rad: float) -> Similarity:
        """The rigid motion turning by angle_rad about the hinge (right-handed about `axis`)."""
        T = turn_about(self.point, self.axis, angle_rad)
        return Similarity(1.0, T[:3, :3], T[:3, 3])


def find_hinge(part: np.ndarray, anchor: np.ndarray, attach_m: float = ATTACH_M) -> Hinge:
    """The hinge line of `part` (N, 3) on `anchor` (M, 3); HingeNotFound says why there is none."""
    if len(part) == 0 or len(anchor) == 0:
        raise HingeNotFound("the part or its anchor has no 3D points")
    d, _ = cKDTree(anchor).query(part, distance_upper_bound=attach_m)
    attached = part[np.isfinite(d)]
    if len(attached) < MIN_ATTACH_POINTS:
        raise HingeNotFound(
            f"the part does not meet its anchor: {len(attached)} of its points lie within {attach_m * 1000:.0f} mm "
            f"of it (need {MIN_ATTACH_POINTS})"
        )
    centre = attached.mean(axis=0)
    _, spread, axes = np.linalg.svd(attached - centre, full_matrices=False)
    if spread[1] > 0 and spread[0] / spread[1] < MIN_ELONGATION:
        raise HingeNotFound(
            f"where the part meets its anchor is no line (extents {spread[0] / np.sqrt(len(attached)) * 1000:.0f} "
            f"and {spread[1] / np.sqrt(len(attached)) * 1000:.0f} mm): no hinge to turn about"
        )
    axis = axes[0]
    away = part.mean(axis=0) - centre  # across the hinge, into the part
    away -= (away @ axis) * axis
    if np.linalg.norm(away) > 1e-9:
        away /= np.linalg.norm(away)
        centre = centre + np.percentile((attached - centre) @ away, HINGE_EDGE_PERCENTILE) * away
    return Hinge(centre, axis, attached)


def silhouette(points: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """Pixels covered by points (N, 3) in the camera frame, gaps between neighbouring points closed."""
    mask = np.zeros((K.height, K.width), np.uint8)
    front = points[points[:, 2] > 1e-3]
    if len(front):
        uv = np.round(K.project(front)).astype(int)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < K.width) & (uv[:, 1] >= 0) & (uv[:, 1] < K.height)
        mask[uv[inside, 1], uv[inside, 0]] = 1
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8)).astype(bool)


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 0.0


def turn_agreement(
    hinge: Hinge,
    angle_rad: float,
    cloud0: np.ndarray,
    cloud1: np.ndarray,
    mask0: np.ndarray,
    mask1: np.ndarray,
    K: CameraIntrinsics,
) -> float:
    """Mean silhouette IoU of the initial part turned into the goal view and the goal part turned back."""
    motion = hinge.turn(angle_rad)
    back = hinge.turn(-angle_rad)
    return 0.5 * (_iou(silhouette(motion.apply(cloud0), K), mask1) + _iou(silhouette(back.apply(cloud1), K), mask0))


def best_turn(
    hinge: Hinge, cloud0: np.ndarray, cloud1: np.ndarray, mask0: np.ndarray, mask1: np.ndarray, K: CameraIntrinsics
) -> tuple[float, float]:
    """(angle [rad], silhouette agreement) of the best turn: a coarse sweep over every angle, then a fine one."""

    def score(deg: float) -> float:
        return turn_agreement(hinge, np.radians(deg), cloud0, cloud1, mask0, mask1, K)

    coarse = np.arange(-180.0, 180.0, COARSE_STEP_DEG)
    start = float(coarse[int(np.argmax([score(a) for a in coarse]))])
    fine = start + np.arange(-FINE_SPAN_DEG, FINE_SPAN_DEG + 1e-9, FINE_STEP_DEG)
    scores = [score(a) for a in fine]
    best = int(np.argmax(scores))
    return float(np.radians(fine[best])), float(scores[best])
