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


def support_height(fp: Footprint, plane: Plane, centre: np.ndarray | None = None, container: bool = False) -> float:
    """Height of the surface an object placed at `centre` (default: the footprint's) would rest on (top of a
    plate, floor of a pan): the points seen around it. None seen there: the object's top, or a container's base
    (its lowest points): walls taller than the view into it hide its floor, which lies at its foot, not its rim."""
    q = plane.project(fp.points)
    at = fp.centre if centre is None else centre
    near = np.linalg.norm(q - at, axis=1) < 0.5 * max(fp.radius_m, 0.01)
    if near.any():
        return float(np.median(fp.heights[near]))
    return float(np.percentile(fp.heights, 2) if container else fp.heights.max())


TOP_BAND_M = 0.01  # an object's top: its points this close below its highest
CELL_M = 0.005  # top points are thinned to one per cell of the plane: a near face shows more pixels, not more top


def _top(fp: Footprint, plane: Plane) -> np.ndarray:
    """The object's top points projected on the plane, one per CELL_M cell (in-plane coordinates (N, 2) and the
    basis), so every part of the top counts by its area, not by how near the camera it is."""
    top = fp.points[fp.heights >= np.percentile(fp.heights, 98) - TOP_BAND_M]
    u = plane.in_plane(np.array([1.0, 0.0, 0.0]) if abs(plane.n[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
    v = np.cross(plane.n, u)
    q = plane.project(top)
    uv = np.column_stack([q @ u, q @ v])
    _, first = np.unique(np.floor(uv / CELL_M).astype(np.int64), axis=0, return_index=True)
    return uv[first], np.stack([u, v])


def _from_uv(uv: np.ndarray, basis: np.ndarray, plane: Plane) -> np.ndarray:
    return plane.project(uv @ basis)


def top_centre(fp: Footprint, plane: Plane) -> np.ndarray:
    """Centre (on the plane) of the object's top as seen from above: the middle of a block's top face, of a lying
    bottle's ridge, of a ball's cap. Unlike the footprint's centre (the median of every seen point), it is not
    pulled toward the side the camera sees."""
    uv, basis = _top(fp, plane)
    return _from_uv(uv.mean(axis=0), basis, plane)


def rim_centre(fp: Footprint, plane: Plane, seed: int = 0) -> np.ndarray:
    """Centre (on the plane) of a container's rim: the circle through most of its top points (RANSAC, then least
    squares on its inliers), which a pan's handle beside it does not pull; the top's centre when no circle of a
    container's size holds most of them."""
    uv, basis = _top(fp, plane)
    best, best_count = None, 0
    rng = np.random.default_rng(seed)
    for _ in range(200 if len(uv) >= 3 else 0):
        fit = _circle(uv[rng.choice(len(uv), 3, replace=False)])
        if fit is None or not 0.02 <= fit[1] <= 0.2:
            continue
        inliers = np.abs(np.linalg.norm(uv - fit[0], axis=1) - fit[1]) < CELL_M
        if inliers.sum() > best_count:
            best, best_count = inliers, int(inliers.sum())
    if best is None or best_count < 0.5 * len(uv):
        return top_centre(fp, plane)
    fit = _circle(uv[best])
    return top_centre(fp, plane) if fit is None else _from_uv(fit[0], basis, plane)


def _circle(uv: np.ndarray) -> tuple[np.ndarray, float] | None:
    """Least-squares circle (centre, radius) through points (N >= 3, 2): x^2 + y^2 = 2 c.x + k."""
    A = np.column_stack([2 * uv, np.ones(len(uv))])
    solution, _, rank, _ = np.linalg.lstsq(A, (uv**2).sum(axis=1), rcond=None)
    if rank < 3:
        return None
    centre = solution[:2]
    r2 = solution[2] + centre @ centre
    return (centre, float(np.sqrt(r2))) if r2 > 0 else None


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
