"""A box's turn about the vertical, read from the goal mask's outline.

A model's goal depth tilts a small box's faces by 5-10 deg (its edges bled into what lies behind them, the noise
smoothed over that bleed, a slow warp left under it), and the registration follows: boxes standing on the table came
out turned 6-25 deg about the vertical from where the goal image shows them (raycast pairs). The outline does not
depend on that depth. A box's outline is the convex hull of its eight corners' images: the capture's measured points
give the box (seen_symmetry.seen_box), the motion carries it to the goal, and of its turns about the vertical through
its goal centre the one is taken whose hull lies along the goal mask's outline. A segmenter's outline is a few pixels
out all round (dilated or eroded), ragged, with holes: the fit takes out a uniform offset along the outline's normals
and a shift of the whole outline (where the depth put it, which the support corrects, ray_rest.py), fills the holes,
and bounds what a stretch far off counts (something in front hiding part of the box, a neighbour bled onto).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.seen_symmetry import SeenBox
from pipeline.grounding.silhouette import largest_outline
from pipeline.grounding.umeyama import Similarity

SPAN_DEG, STEP_DEG = 30.0, 1.0  # turns tried either way about the vertical, and their step
OFF_PX = 3.0  # a stretch of the hull farther than this from the fitted outline counts as this far (hidden, bled)
ROBUST_ROUNDS = 3
MARGIN_PX = 24  # the distances are read this far round the mask's outline; farther, a hull is off anyway
HIDDEN_PROBE_PX = 4  # the goal depth read this far outside the outline (past a model's bleed of its edge) ...
IN_FRONT_M = 0.02  # ... this much nearer than the box's edge: something in front hides that stretch (a model's
# depth is good to a centimetre or so there)
MIN_SEEN_PX = 20  # an outline with fewer pixels in view than this shows no turn
MIN_ALONG = 0.7  # the hull's share within OFF_PX of the outline at its best turn: less, and it is not this box's


def turned_to_outline(
    motion: Similarity, box: SeenBox, up: np.ndarray, mask1: np.ndarray, depth1: np.ndarray, K: CameraIntrinsics
) -> Similarity:
    """`motion` turned about the vertical `up` (unit, camera frame) through the box's goal centre so that the goal
    box's outline lies along the goal mask's; `motion` itself where the mask's outline touches the image's edge or
    no turn fits it (MIN_ALONG). `depth1`: the goal's metric depth, to tell where something in front hides the
    outline."""
    outline = largest_outline(mask1)
    if outline is None:
        return motion
    distance, corner = _signed_distance(outline, mask1.shape)
    centre = motion.apply(box.centre[None])[0]
    goal = motion.apply(box.corners) - centre
    angles = np.radians(np.arange(-SPAN_DEG, SPAN_DEG + 1e-9, STEP_DEG))
    turned = np.einsum("aij,cj->aci", Rotation.from_rotvec(angles[:, None] * up).as_matrix(), goal) + centre
    costs, along = _misfits(turned, distance, corner, depth1, K)
    best = int(np.argmin(costs))
    if along[best] < MIN_ALONG:
        return motion
    Y = Rotation.from_rotvec((angles[best] + np.radians(STEP_DEG) * _vertex(costs, best)) * up).as_matrix()
    return Similarity(motion.scale, Y @ motion.R, Y @ (motion.t - centre) + centre)


def _vertex(costs: np.ndarray, k: int) -> float:
    """Where, in steps from k, the parabola through costs k-1, k, k+1 is lowest (0 at either end or where flat)."""
    if not 0 < k < len(costs) - 1:
        return 0.0
    a, b, c = costs[k - 1 : k + 2]
    curve = a - 2 * b + c
    return float(np.clip(0.5 * (a - c) / curve, -0.5, 0.5)) if curve > 0 else 0.0


def _signed_distance(outline: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """(each pixel's distance (px) to the filled outline's edge, positive outside it and negative inside (holes
    filled), over the outline's bounding box widened by MARGIN_PX; that box's top-left pixel (u, v))."""
    x, y, w, h = cv2.boundingRect(outline)
    x0, y0 = max(x - MARGIN_PX, 0), max(y - MARGIN_PX, 0)
    x1, y1 = min(x + w + MARGIN_PX, shape[1]), min(y + h + MARGIN_PX, shape[0])
    filled = np.zeros((y1 - y0, x1 - x0), np.uint8)
    cv2.drawContours(filled, [outline], -1, 1, thickness=cv2.FILLED, offset=(-x0, -y0))
    outside = cv2.distanceTransform(1 - filled, cv2.DIST_L2, 5)
    inside = cv2.distanceTransform(filled, cv2.DIST_L2, 5)
    return outside - inside, np.array([x0, y0], dtype=np.float64)


def _hull_edges(corner_sets: np.ndarray, K: CameraIntrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(points (P, 2), outward unit normals (P, 2), their depth [m] (P,), which set each is from (P,)): the outline
    of each set of corners' images (A, C, 3), their convex hull, sampled about every pixel."""
    starts, ends, owner = [], [], []
    for k, corners in enumerate(corner_sets):
        uv = K.project(corners)
        hull = cv2.convexHull(uv.astype(np.float32), returnPoints=False).ravel()
        vertices = np.column_stack([uv[hull], corners[hull, 2]])
        starts.append(vertices)
        ends.append(np.roll(vertices, -1, axis=0))
        owner.append(np.full(len(hull), k))
    a, b, owner = np.concatenate(starts), np.concatenate(ends), np.concatenate(owner)
    edge = b[:, :2] - a[:, :2]
    length = np.maximum(np.linalg.norm(edge, axis=1), 1e-9)
    count = np.maximum(2, length.astype(int))
    which = np.repeat(np.arange(len(a)), count)
    first = np.cumsum(count) - count
    along = (np.arange(len(which)) - first[which] + 0.5) / count[which]
    points = a[which] + along[:, None] * (b - a)[which]
    normals = np.column_stack([edge[:, 1], -edge[:, 0]]) / length[:, None]  # outward on a counter-clockwise hull ...
    middle = np.stack([v[:, :2].mean(axis=0) for v in starts])
    flip = np.einsum("ij,ij->i", normals, a[:, :2] - middle[owner]) < 0  # ... whichever way OpenCV ran it
    normals[flip] *= -1
    return points[:, :2], normals[which], points[:, 2], owner[which]


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


def _misfits(
    corner_sets: np.ndarray, distance: np.ndarray, corner: np.ndarray, depth1: np.ndarray, K: CameraIntrinsics
) -> tuple[np.ndarray, np.ndarray]:
    """For each set of corners (A, C, 3): (the mean squared distance (px^2, each at most OFF_PX) of its outline from
    the mask's once a uniform offset and a shift are taken out, the share of its outline within OFF_PX), over the
    stretches of its outline that nothing in front hides (_in_view)."""
    points, normals, z, owner = _hull_edges(corner_sets, K)
    seen = _in_view(points + HIDDEN_PROBE_PX * normals, z, depth1)
    points, normals, owner = points[seen], normals[seen], owner[seen]
    d = _sampled(distance, corner, points)
    A = np.column_stack([np.ones(len(d)), normals])  # d = offset + normal . shift along an outline that fits
    sets = len(corner_sets)
    near = np.ones(len(d))
    for _ in range(ROBUST_ROUNDS):
        AtA = np.stack([np.bincount(owner, A[:, i] * A[:, j] * near, sets) for i in range(3) for j in range(3)], 1)
        Atd = np.stack([np.bincount(owner, A[:, i] * d * near, sets) for i in range(3)], 1)
        fit = np.linalg.solve(AtA.reshape(sets, 3, 3) + 1e-9 * np.eye(3), Atd[..., None])[..., 0]
        off = np.abs(d - np.einsum("pi,pi->p", A, fit[owner]))
        near = (off < OFF_PX).astype(float)
    count = np.bincount(owner, minlength=sets)
    few = count < MIN_SEEN_PX  # a turn that puts most of the outline behind something in front shows nothing
    costs = np.bincount(owner, np.minimum(off, OFF_PX) ** 2, sets) / np.maximum(count, 1)
    return np.where(few, np.inf, costs), np.bincount(owner, near, sets) / np.maximum(count, 1)


def _in_view(probes: np.ndarray, z: np.ndarray, depth1: np.ndarray) -> np.ndarray:
    """Whether each stretch of an outline at depth z [m] (P,) is the object's own edge: the goal depth just outside it
    (at `probes`, (P, 2) pixels) not IN_FRONT_M nearer than the edge (where it is, something in front of the
    object ends there, not the object)."""
    u = np.clip(np.round(probes[:, 0]).astype(int), 0, depth1.shape[1] - 1)
    v = np.clip(np.round(probes[:, 1]).astype(int), 0, depth1.shape[0] - 1)
    outside = depth1[v, u]
    return ~(outside < z - IN_FRONT_M)  # NaN: nothing known in front
