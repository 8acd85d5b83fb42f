"""Footprints on the table: the area an object covers seen from above, as convex polygons in the table plane.

Placement keeps footprints apart by a gap. A footprint is the object's true outline (a pan with its handle, a
lying bottle's full length, an open lid leaning past upright), not a circle around its centre, so a long part
cannot reach into a neighbour that a radius test would have let through.
"""

from __future__ import annotations

import math

import numpy as np

DISC_SIDES = 24


def rectangle(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """Axis-aligned rectangle [m] as a (4, 2) polygon, counterclockwise."""
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def disc(radius: float, centre: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """A regular polygon around a circle of `radius` (circumscribed: it covers the whole disc)."""
    a = np.linspace(0.0, 2 * math.pi, DISC_SIDES, endpoint=False)
    r = radius / math.cos(math.pi / DISC_SIDES)
    return np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)])


def moved(polygon: np.ndarray, x: float, y: float, yaw: float) -> np.ndarray:
    """The polygon of an object's frame placed at (x, y) turned by yaw [rad] about the vertical."""
    c, s = math.cos(yaw), math.sin(yaw)
    return polygon @ np.array([[c, s], [-s, c]]) + (x, y)


def _separated(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test of two convex polygons: True when an edge normal of either separates them."""
    for p in (a, b):
        edges = np.roll(p, -1, axis=0) - p
        normals = np.column_stack([-edges[:, 1], edges[:, 0]])
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(axis=0) < pb.min(axis=0)) | (pb.max(axis=0) < pa.min(axis=0))):
            return True
    return False


def _point_segment_distances(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Distance of each point to each edge of the polygon, (N, M)."""
    a = polygon
    ab = np.roll(polygon, -1, axis=0) - a
    ap = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("nmk,mk->nm", ap, ab) / np.maximum(np.einsum("mk,mk->m", ab, ab), 1e-18), 0.0, 1.0)
    return np.linalg.norm(ap - t[..., None] * ab[None], axis=2)


def gap(a: np.ndarray, b: np.ndarray) -> float:
    """Distance [m] between two convex polygons; 0 when they touch or overlap."""
    if not _separated(a, b):
        return 0.0
    return float(min(_point_segment_distances(a, b).min(), _point_segment_distances(b, a).min()))


def footprint_gap(a: list[np.ndarray], b: list[np.ndarray]) -> float:
    """Distance between two footprints, each a union of convex polygons."""
    return min(gap(p, q) for p in a for q in b)
