"""Table-top geometry from one depth frame: the support plane, object footprints, rotations about axes.

Used by the offline editor to decide where an object goes ("on the plate", "left of the can") in metric terms,
from the observed depth only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics


class GeometryError(ValueError):
    pass


@dataclass(frozen=True)
class Plane:
    """n . p + d = 0 in the camera frame, n unit and pointing to the camera side (up from the table)."""

    n: np.ndarray
    d: float

    def height(self, p: np.ndarray) -> np.ndarray:
        return p @ self.n + self.d

    def project(self, p: np.ndarray) -> np.ndarray:
        return p - self.height(p)[..., None] * self.n

    def in_plane(self, v: np.ndarray) -> np.ndarray:
        """Unit vector of `v` projected onto the plane directions."""
        w = v - (v @ self.n) * self.n
        norm = np.linalg.norm(w)
        if norm < 1e-9:
            raise GeometryError("direction is perpendicular to the table plane")
        return w / norm

    def ray_depth(self, K: CameraIntrinsics, uv: np.ndarray) -> np.ndarray:
        """Depth (z) where the camera rays through pixels uv (N, 2) meet the plane; NaN if parallel or behind."""
        rays = np.stack([(uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy, np.ones(len(uv))], axis=1)
        denom = rays @ self.n
        with np.errstate(divide="ignore", invalid="ignore"):
            z = -self.d / denom
        return np.where(z > 0, z, np.nan)


def fit_table_plane(points: np.ndarray, tol_m: float = 0.006, iterations: int = 300, seed: int = 0) -> Plane:
    """RANSAC plane through the largest flat set of points (the table dominates a table-top view), refit by SVD."""
    p = points[np.all(np.isfinite(points), axis=1)]
    if len(p) < 100:
        raise GeometryError(f"table plane: only {len(p)} valid depth points")
    rng = np.random.default_rng(seed)
    best, best_count = None, 0
    for _ in range(iterations):
        a, b, c = p[rng.choice(len(p), 3, replace=False)]
        n = np.cross(b - a, c - a)
        if np.linalg.norm(n) < 1e-9:
            continue
        n /= np.linalg.norm(n)
        inl = np.abs((p - a) @ n) < tol_m
        if inl.sum() > best_count:
            best, best_count = inl, int(inl.sum())
    if best is None or best_count < 0.2 * len(p):
        raise GeometryError(f"table plane: best plane holds {best_count} of {len(p)} points (< 20 %)")
    q = p[best]
    centre = q.mean(axis=0)
    n = np.linalg.eigh(np.cov((q - centre).T))[1][:, 0]
    if n @ -centre < 0:  # the camera (origin) is on the positive side
        n = -n
    return Plane(n, float(-n @ centre))


def object_points(depth_m: np.ndarray, K: CameraIntrinsics, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (N, 3) and pixels (N, 2) of every mask pixel; invalid depth takes the nearest valid."""
    valid = mask & np.isfinite(depth_m)
    if valid.sum() < 0.3 * mask.sum() or valid.sum() < 10:
        raise GeometryError(f"object has valid depth on {valid.sum()} of {mask.sum()} pixels")
    _, (iv, iu) = distance_transform_edt(~valid, return_indices=True)
    filled = depth_m[iv, iu]
    v, u = np.nonzero(mask)
    uv = np.stack([u, v], axis=1).astype(np.float64)
    return K.unproject(uv, filled[v, u]), uv


@dataclass(frozen=True)
class Footprint:
    centre: np.ndarray  # on the plane
    radius_m: float  # 90th percentile of in-plane distance from the centre
    heights: np.ndarray  # per point, above the plane
    points: np.ndarray


def footprint(points: np.ndarray, plane: Plane) -> Footprint:
    q = plane.project(points)
    centre = np.median(q, axis=0)
    centre = plane.project(centre)
    r = float(np.percentile(np.linalg.norm(q - centre, axis=1), 90))
    return Footprint(centre, r, plane.height(points), points)


def support_height(fp: Footprint, plane: Plane) -> float:
    """Height of the surface an object placed at the centre would rest on (top of a plate, floor of a pan)."""
    q = plane.project(fp.points)
    near = np.linalg.norm(q - fp.centre, axis=1) < 0.5 * max(fp.radius_m, 0.01)
    return float(np.median(fp.heights[near])) if near.any() else float(fp.heights.max())


def axis_rotation(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    return Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle_rad).as_matrix()


def principal_axis(fp: Footprint, plane: Plane) -> np.ndarray:
    """Long horizontal axis of an object (unit, in the plane)."""
    q = plane.project(fp.points) - fp.centre
    _, _, vt = np.linalg.svd(q, full_matrices=False)
    return plane.in_plane(vt[0])


def wide_end(fp: Footprint, plane: Plane, axis: np.ndarray, end_fraction: float = 0.2) -> float:
    """+1 if the object's +axis end is wider than its -axis end (a bottle's base against its neck), -1 if
    narrower, 0 if the two ends are within 15 % (a plain cylinder): width is the spread across the axis of the
    points in the outer `end_fraction` of the length at each end."""
    q = plane.project(fp.points) - fp.centre
    s, w = q @ axis, q @ np.cross(plane.n, axis)
    lo, hi = np.percentile(s, [1, 99])
    cut = end_fraction * (hi - lo)

    def spread(sel: np.ndarray) -> float:
        return float(np.percentile(w[sel], 95) - np.percentile(w[sel], 5)) if sel.sum() >= 10 else 0.0

    plus, minus = spread(s >= hi - cut), spread(s <= lo + cut)
    if abs(plus - minus) < 0.15 * max(plus, minus, 1e-9):
        return 0.0
    return 1.0 if plus > minus else -1.0
