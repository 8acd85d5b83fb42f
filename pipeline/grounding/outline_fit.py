"""How well a body's outline, as a motion puts it in the goal image, lies along the goal mask's.

The goal mask's outline does not depend on the model's goal depth, which bleeds, warps and tilts a small object's
surface by degrees and puts it centimetres off (prepare.py). A body whose whole shape the capture gives (a box's
corners, a body of revolution's seen slices spun round its axis, a handled body's with its handle) casts, as a
convex body would, the convex hull of its points' images; it is compared with the convex hull of the goal mask's
largest outline. A segmenter's outline is a few pixels out all round (dilated or eroded), ragged, with holes, and a
body's hull is no finer than its points: the fit takes out a uniform offset along the hull's normals and a shift of
the whole hull by least squares, bounds what a stretch far off counts (OFF_PX: a neighbour bled onto) and leaves out
the stretches that something in front hides (the goal depth just outside them nearer than the body's edge). What
remains is the misfit of the body's shape; the shift is where the image shows the body across the camera ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.silhouette import largest_outline

OFF_PX = 3.0  # a stretch of the hull farther than this from the fitted outline counts as this far (hidden, bled)
ROBUST_ROUNDS = 3
MARGIN_PX = 24  # the distances are read this far round the mask's outline; farther, a hull is off anyway
HIDDEN_PROBE_PX = 4  # the goal depth read this far outside the hull (past a model's bleed of its edge) ...
IN_FRONT_M = 0.02  # ... this much nearer than the body's edge: something in front hides that stretch (a model's
# depth is good to a centimetre or so there)
MIN_SEEN_PX = 20  # a hull with fewer pixels in view than this shows nothing
MIN_DEPTH_M = 1e-3  # a set of points reaching nearer the camera than this casts no outline


@dataclass(frozen=True)
class OutlineFits:
    """Per set of points (A,): the misfit (mean squared distance, px^2, each at most OFF_PX) of its hull from the goal
    outline once the offset and shift are out (inf where too little of it is in view), the share of the hull within
    OFF_PX, and the image move (px, (A, 2)) that lays the hull on the outline."""

    cost: np.ndarray
    along: np.ndarray
    move_px: np.ndarray


@dataclass(frozen=True)
class GoalOutline:
    """The goal mask's outline as a signed distance (px, positive outside the filled convex hull of its largest outline,
    over its bounding box widened by MARGIN_PX, whose top-left pixel is `corner`), with the goal's metric depth."""

    distance: np.ndarray
    corner: np.ndarray
    depth: np.ndarray
    K: CameraIntrinsics

    def fits(self, point_sets: np.ndarray) -> OutlineFits:
        """How each set of camera-frame points (A, N, 3) casts its hull on the outline."""
        points, normals, z, owner = _hull_edges(point_sets, self.K)
        seen = _in_view(points + HIDDEN_PROBE_PX * normals, z, self.depth)
        points, normals, owner = points[seen], normals[seen], owner[seen]
        d = _sampled(self.distance, self.corner, points)
        A = np.column_stack([np.ones(len(d)), normals])  # d = offset + normal . shift along a hull that fits
        sets = len(point_sets)
        near = np.ones(len(d))
        fit = np.zeros((sets, 3))
        for _ in range(ROBUST_ROUNDS):
            AtA = np.stack([np.bincount(owner, A[:, i] * A[:, j] * near, sets) for i in range(3) for j in range(3)], 1)
            Atd = np.stack([np.bincount(owner, A[:, i] * d * near, sets) for i in range(3)], 1)
            fit = np.linalg.solve(AtA.reshape(sets, 3, 3) + 1e-9 * np.eye(3), Atd[..., None])[..., 0]
            off = np.abs(d - np.einsum("pi,pi->p", A, fit[owner]))
            near = (off < OFF_PX).astype(float)
        count = np.bincount(owner, minlength=sets)
        cost = np.bincount(owner, np.minimum(off, OFF_PX) ** 2, sets) / np.maximum(count, 1)
        along = np.bincount(owner, near, sets) / np.maximum(count, 1)
        return OutlineFits(np.where(count < MIN_SEEN_PX, np.inf, cost), along, -fit[:, 1:])


def goal_outline(mask1: np.ndarray, depth1: np.ndarray, K: CameraIntrinsics) -> GoalOutline | None:
    """The goal mask's outline, or None where the image's edge cuts it."""
    outline = largest_outline(mask1)
    if outline is None:
        return None
    hull = cv2.convexHull(outline)
    x, y, w, h = cv2.boundingRect(hull)
    x0, y0 = max(x - MARGIN_PX, 0), max(y - MARGIN_PX, 0)
    x1, y1 = min(x + w + MARGIN_PX, mask1.shape[1]), min(y + h + MARGIN_PX, mask1.shape[0])
    filled = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.drawContours(filled, [hull], -1, 1, thickness=cv2.FILLED, offset=(-x0, -y0))
    distance = cv2.distanceTransform(1 - filled, cv2.DIST_L2, 5) - cv2.distanceTransform(filled, cv2.DIST_L2, 5)
    return GoalOutline(distance, np.array([x0, y0], dtype=np.float64), depth1, K)


def turned_about(points: np.ndarray, pivot: np.ndarray, axis: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """(A, N, 3): the points (N, 3, camera frame) turned by each of the angles (A,, rad) about the unit `axis` through
    `pivot`, as sets to fit (GoalOutline.fits)."""
    turns = Rotation.from_rotvec(angles[:, None] * axis).as_matrix()
    return np.einsum("aij,nj->ani", turns, points - pivot) + pivot


def refined_angle(cost: np.ndarray, angles: np.ndarray, best: int) -> float:
    """The angle [rad] at the vertex of the parabola through the costs (A,) of evenly spaced `angles` at `best` and
    its two neighbours; `angles[best]` itself at either end."""
    vertex = parabola_vertex(*cost[best - 1 : best + 2]) if 0 < best < len(angles) - 1 else 0.0
    return float(angles[best] + (angles[1] - angles[0]) * vertex)


def parabola_vertex(a: float, b: float, c: float) -> float:
    """Where, in steps from the middle one, the parabola through three costs a step apart is lowest (0 where flat, or
    where a cost is infinite: a hull hidden there)."""
    if not np.isfinite([a, b, c]).all():
        return 0.0
    curve = a - 2 * b + c
    return float(np.clip(0.5 * (a - c) / curve, -0.5, 0.5)) if curve > 0 else 0.0


def _hull_edges(point_sets: np.ndarray, K: CameraIntrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(points (P, 2), outward unit normals (P, 2), their depth [m] (P,), which set each is from (P,)): the outline
    of each set of points' images (A, N, 3), their convex hull, sampled about every pixel. A set with a point at or
    behind the camera, or with fewer than 3 points, casts none."""
    starts, ends, owner = [], [], []
    middle = np.zeros((len(point_sets), 2))
    for k, points in enumerate(point_sets):
        if len(points) < 3 or not np.all(points[:, 2] > MIN_DEPTH_M):
            continue
        uv = K.project(points)
        hull = cv2.convexHull(uv.astype(np.float32), returnPoints=False).ravel()
        vertices = np.column_stack([uv[hull], points[hull, 2]])
        starts.append(vertices)
        ends.append(np.roll(vertices, -1, axis=0))
        owner.append(np.full(len(hull), k))
        middle[k] = uv[hull].mean(axis=0)
    if not starts:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=int)
    a, b, owner = np.concatenate(starts), np.concatenate(ends), np.concatenate(owner)
    edge = b[:, :2] - a[:, :2]
    length = np.maximum(np.linalg.norm(edge, axis=1), 1e-9)
    count = np.maximum(2, length.astype(int))
    which = np.repeat(np.arange(len(a)), count)
    first = np.cumsum(count) - count
    along = (np.arange(len(which)) - first[which] + 0.5) / count[which]
    samples = a[which] + along[:, None] * (b - a)[which]
    normals = np.column_stack([edge[:, 1], -edge[:, 0]]) / length[:, None]  # outward on a counter-clockwise hull ...
    flip = np.einsum("ij,ij->i", normals, a[:, :2] - middle[owner]) < 0  # ... whichever way OpenCV ran it
    normals[flip] *= -1
    return samples[:, :2], normals[which], samples[:, 2], owner[which]


def _sampled(image: np.ndarray, corner: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The image's values at the points (P, 2, pixels (u, v) of the whole image), bilinear, its edge's beyond it."""
    u, v = (points - corner).T
    u = np.clip(u, 0, image.shape[1] - 1.001)
    v = np.clip(v, 0, image.shape[0] - 1.001)
    i, j = v.astype(int), u.astype(int)
    fv, fu = v - i, u - j
    top = image[i, j] * (1 - fu) + image[i, j + 1] * fu
    bottom = image[i + 1, j] * (1 - fu) + image[i + 1, j + 1] * fu
    return top * (1 - fv) + bottom * fv


def _in_view(probes: np.ndarray, z: np.ndarray, depth1: np.ndarray) -> np.ndarray:
    """Whether each stretch of a hull at depth z [m] (P,) is the body's own edge: the goal depth just outside it (at
    `probes`, (P, 2) pixels) not IN_FRONT_M nearer than the edge (where it is, something in front of the body ends
    there, not the body)."""
    u = np.clip(np.round(probes[:, 0]).astype(int), 0, depth1.shape[1] - 1)
    v = np.clip(np.round(probes[:, 1]).astype(int), 0, depth1.shape[0] - 1)
    return ~(depth1[v, u] < z - IN_FRONT_M)  # NaN: nothing known in front
