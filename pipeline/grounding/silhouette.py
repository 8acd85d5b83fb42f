"""Where the goal lies across the camera ray, read from the goal mask's outline for shapes whose outline tells it.

A model's goal depth can flatten a small object, bend it with a slow warp or bleed it into what is behind, and ICP
onto it puts the object millimetres to centimetres to one side of where the goal image shows it (a ball slid across
the table came out 25 mm off across the ray, a can 9 mm). The outline does not depend on that depth, and a
segmenter's errors (an outline a few pixels out, holes) leave what is read here in place:

- a ball: its outline is a near-circle centred on the image of its centre (within a fraction of a pixel at tabletop
  distances), so its centre lies on the ray through the centre of the filled outline (silhouette_ray);
- a body of revolution: the plane through the camera and its axis is a plane of symmetry of the body and the camera
  together, so the outline is symmetric about it: seen round the line through the camera parallel to the axis, each
  band of the outline at one height spans azimuths symmetric about that plane's (mirror_plane).

On raycast pairs the ray through a ball's outline passed 0.1-1.5 mm from its true centre and the true axis of a
standing body lay within 0.3 mm of the plane read (a few partly hidden ones 1-6 mm, which the bands' disagreement
shows), where the answers were up to 25 and 12 mm off across the ray. How far the object lies along the ray is the
support's to tell (ray_rest.py). An outline cut by the image's edge is not used, nor one that is not round (a ball
partly hidden) or whose bands do not agree on one plane (a handle, a body partly hidden).
"""

from __future__ import annotations

import cv2
import numpy as np

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
    outline = largest_outline(mask)
    if outline is None:
        return None
    filled = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(filled, [outline], -1, 1, thickness=cv2.FILLED)
    v, u = np.nonzero(filled)
    rays = _unit_rays(np.column_stack([u, v]), K)
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
    if np.std(mids) > MIRROR_SPREAD_REL * np.median(halves):
        return None
    phi = middle + float(np.median(mids))
    return np.sin(phi) * e1 - np.cos(phi) * e2  # across the plane spanned by the axis and cos(phi) e1 + sin(phi) e2


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
