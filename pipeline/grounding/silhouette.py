"""Where the goal lies across the camera ray, read from the goal mask's outline for shapes whose outline tells it.

A model's goal depth can flatten a small object, bend it with a slow warp or bleed it into what is behind, and ICP
onto it puts the object millimetres to centimetres to one side of where the goal image shows it (a ball slid across
the table came out 25 mm off across the ray, a can 9 mm). The outline does not depend on that depth, and a
segmenter's errors (an outline a few pixels out, holes) leave what is read here in place:

- a ball: its outline is a near-circle centred on the image of its centre (within a fraction of a pixel at tabletop
  distances), so its centre lies on the ray through the centre of the filled outline (silhouette_ray);
- a body of revolution: the plane through the camera and its axis is a plane of symmetry of the body and the camera
  together, so the outline is symmetric about it: seen round the line through the camera parallel to the axis, each
  band of the outline at one height spans azimuths symmetric about that plane's (mirror_plane); the same symmetry,
  sought over turns of a tipped body's axis about the goal ray, gives that axis's direction across the ray
  (axis_turned_to_outline).

On raycast pairs the ray through a ball's outline passed 0.1-1.5 mm from its true centre and the true axis of a
standing body lay within 0.3 mm of the plane read (a few partly hidden ones 1-6 mm, which the bands' disagreement
shows), where the answers were up to 25 and 12 mm off across the ray. How far the object lies along the ray is the
support's to tell (ray_rest.py). An outline cut by the image's edge is not used, nor one that is not round (a ball
partly hidden) or whose bands do not agree on one plane (a handle, a body partly hidden).
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.contact.symmetry import basis_across
from pipeline.grounding.umeyama import Similarity

EDGE_PX = 2  # an outline this close to the image's edge may be cut by it
ROUND_FILL = 0.7  # a ball's filled outline covers this share of its enclosing circle (raycast balls: 0.75-0.96)
BANDS = 24  # bands of the outline across the axis, from its lowest ray to its highest
MIN_BAND_PX = 10  # a band is read where it holds this many pixels ...
MIN_BANDS = 6  # ... and the plane where this many bands are read
MIRROR_SPREAD_REL = 0.1  # the bands' middles agree this well: their spread (std) over the outline's half-width
# (raycast goals of standing bodies of revolution: 0.003-0.05; partly hidden or bled onto a neighbour: 0.18 and up)
TURN_RANGE_DEG = 16.0  # a tipped body's axis turned about the goal ray this far either way ...
TURN_STEP_DEG = (2.0, 0.5)  # ... coarse, then fine about the best
TURN_GAIN = 0.7  # the turn is taken where it brings the bands' spread under this share of the motion's own


def silhouette_ray(mask: np.ndarray, K: CameraIntrinsics) -> np.ndarray | None:
    """(3,) unit camera-frame ray through the centre of the mask's largest outline, filled; None where that outline
    is not round or touches the image's edge."""
    outline = largest_outline(mask)
    if outline is None:
        return None
    _, radius = cv2.minEnclosingCircle(outline)
    moments = cv2.moments(outline)
    if moments["m00"] < ROUND_FILL * np.pi * radius**2:
        return None
    return _unit_rays(np.array([[moments["m10"], moments["m01"]]]) / moments["m00"], K)[0]


def mirror_plane(mask: np.ndarray, K: CameraIntrinsics, axis: np.ndarray) -> np.ndarray | None:
    """(3,) unit normal of the plane through the camera, parallel to `axis` (a body of revolution's, camera frame),
    that the mask's largest outline is symmetric about; None where it touches the image's edge or its bands do not
    agree on one plane."""
    rays = _outline_rays(mask, K)
    mirror = None if rays is None else _mirror(rays, axis)
    return None if mirror is None or mirror[1] > MIRROR_SPREAD_REL else mirror[0]


def axis_turned_to_outline(
    motion: Similarity, centre: np.ndarray, axis: np.ndarray, mask: np.ndarray, K: CameraIntrinsics
) -> Similarity:
    """`motion` turned about the ray through where it puts `centre` (the body's middle, as at the start) until the
    goal outline (`mask`) is most nearly symmetric about the plane through the camera and the body's `axis` (as at
    the start, camera frame): the outline shows a tipped body's axis across the ray to a fraction of a degree, where a
    model's goal depth left it 2-15 deg off (raycast bottles, cylinders, bowls and plates tipped). As it is where the
    outline does not tell, is symmetric about no plane within reach (MIRROR_SPREAD_REL; a can whose outline bled
    onto its neighbour grew ever more symmetric toward the range's end) or the turn does not make it clearly more
    symmetric (TURN_GAIN)."""
    rays = _outline_rays(mask, K)
    if rays is None:
        return motion
    goal = motion.apply(centre[None])[0]
    ray = goal / np.linalg.norm(goal)
    direction = motion.R @ (axis / np.linalg.norm(axis))

    def spread(deg: float) -> float:
        mirror = _mirror(rays, Rotation.from_rotvec(np.radians(deg) * ray).apply(direction))
        return np.inf if mirror is None else mirror[1]

    now = spread(0.0)
    if not np.isfinite(now):
        return motion
    coarse = min(np.arange(-TURN_RANGE_DEG, TURN_RANGE_DEG + 1e-9, TURN_STEP_DEG[0]), key=spread)
    fine = np.arange(coarse - TURN_STEP_DEG[0], coarse + TURN_STEP_DEG[0] + 1e-9, TURN_STEP_DEG[1])
    least, best = min((spread(deg), float(deg)) for deg in fine)
    if least > min(TURN_GAIN * now, MIRROR_SPREAD_REL) or abs(best) >= TURN_RANGE_DEG:
        return motion  # no clearer symmetry, or none within reach (still falling at the range's end)
    turn = Rotation.from_rotvec(np.radians(best) * ray).as_matrix()
    return motion.turned_after(turn, goal)


def _outline_rays(mask: np.ndarray, K: CameraIntrinsics) -> np.ndarray | None:
    """(N, 3) unit rays through the pixels of the mask's largest outline, filled; None where it touches the edge."""
    outline = largest_outline(mask)
    if outline is None:
        return None
    filled = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(filled, [outline], -1, 1, thickness=cv2.FILLED)
    v, u = np.nonzero(filled)
    return _unit_rays(np.column_stack([u, v]), K)


def _mirror(rays: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, float] | None:
    """(the unit normal of the plane through the camera, parallel to `axis`, that the outline's `rays` are most
    nearly symmetric about, the spread of its bands' middles over their half-width), None where too few bands."""
    axis = axis / np.linalg.norm(axis)
    e1, e2 = basis_across(axis)
    azimuth = np.arctan2(rays @ e2, rays @ e1)
    middle = float(np.median(azimuth))
    azimuth = np.angle(np.exp(1j * (azimuth - middle)))  # about the outline's middle, clear of the wrap
    height = rays @ axis
    band = np.minimum((BANDS * (height - height.min()) / max(np.ptp(height), 1e-12)).astype(int), BANDS - 1)
    in_bands = (azimuth[band == k] for k in range(BANDS))
    spans = np.array([(a.min(), a.max()) for a in in_bands if len(a) >= MIN_BAND_PX])
    if len(spans) < MIN_BANDS:
        return None
    mids, halves = spans.mean(axis=1), np.ptp(spans, axis=1) / 2
    phi = middle + float(np.median(mids))
    # across the plane spanned by the axis and cos(phi) e1 + sin(phi) e2
    return np.sin(phi) * e1 - np.cos(phi) * e2, float(np.std(mids) / np.median(halves))


def onto_ray(motion: Similarity, point: np.ndarray, ray: np.ndarray) -> Similarity:
    """`motion` shifted so that it puts `point` (3,) on `ray` (3,, unit, camera frame) as far from the camera."""
    goal = motion.apply(point[None])[0]
    return Similarity(motion.scale, motion.R, motion.t + ray * float(np.linalg.norm(goal)) - goal)


def axis_into_plane(
    motion: Similarity, centre: np.ndarray, axis: np.ndarray, mask: np.ndarray, K: CameraIntrinsics
) -> Similarity | None:
    """`motion` shifted across the goal ray so that it puts the body's axis (through `centre`, along `axis`, as at
    the start, camera frame) in the plane its goal outline (`mask`) is symmetric about; None where the outline does
    not tell. The shift carries the start axis's own error where the motion turns the ray to it across the goal
    plane (a turn in place): the axis is fitted least well along that ray (a standing bottle's 2-5 mm, most bodies'
    under 1 mm), and keeping such motions out lost more on the dev seeds than it saved (one bottle turned in place
    0.9 -> 2.6 mm, the translation median better on all three seeds without)."""
    normal = mirror_plane(mask, K, motion.R @ axis)
    if normal is None:
        return None
    goal = motion.apply(centre[None])[0]
    return Similarity(motion.scale, motion.R, motion.t - normal * float(goal @ normal))


def _unit_rays(pixels: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """(N, 3) unit camera-frame rays through pixels (N, 2)."""
    rays = K.unproject(pixels, np.ones(len(pixels)))
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def largest_outline(mask: np.ndarray) -> np.ndarray | None:
    """The mask's largest outline (OpenCV contour), None where there is none or it touches the image's edge."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    outline = max(contours, key=cv2.contourArea)
    x, y, w, h = cv2.boundingRect(outline)
    if x < EDGE_PX or y < EDGE_PX or x + w > mask.shape[1] - EDGE_PX or y + h > mask.shape[0] - EDGE_PX:
        return None
    return outline
