"""Where the goal lies across the camera ray, read from the goal mask's outline for shapes whose outline tells it.

A model's goal depth can flatten a small object, bend it with a slow warp or bleed it into what is behind, and ICP
onto it puts the object millimetres to centimetres to one side of where the goal image shows it (a ball slid across
the table came out 25 mm off across the ray). The outline does not depend on that depth, and a segmenter's errors
(an outline a few pixels out, holes) leave what is read here in place. A ball's outline is a near-circle centred on
the image of its centre (within a fraction of a pixel at tabletop distances), so its centre lies on the ray through
the centre of the filled outline (silhouette_ray): on raycast pairs that ray passed 0.1-1.5 mm from the true centre,
the answers' centres 0.2-25 mm. How far the object lies along the ray is the support's to tell (ray_rest.py). An
outline cut by the image's edge is not used, nor one that is not round (a ball partly hidden).
"""

from __future__ import annotations

import cv2
import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity

EDGE_PX = 2  # an outline this close to the image's edge may be cut by it
ROUND_FILL = 0.7  # a ball's filled outline covers this share of its enclosing circle (raycast balls: 0.75-0.96)


def silhouette_ray(mask: np.ndarray, K: CameraIntrinsics) -> np.ndarray | None:
    """(3,) unit camera-frame ray through the centre of the mask's largest outline, filled; None where that outline
    is not round or touches the image's edge."""
    outline = _outline(mask)
    if outline is None:
        return None
    _, radius = cv2.minEnclosingCircle(outline)
    moments = cv2.moments(outline)
    if moments["m00"] < ROUND_FILL * np.pi * radius**2:
        return None
    u, v = moments["m10"] / moments["m00"], moments["m01"] / moments["m00"]
    ray = np.array([(u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0])
    return ray / np.linalg.norm(ray)


def onto_ray(motion: Similarity, point: np.ndarray, ray: np.ndarray) -> Similarity:
    """`motion` shifted so that it puts `point` (3,) on `ray` (3,, unit, camera frame) as far from the camera."""
    goal = motion.apply(point[None])[0]
    return Similarity(motion.scale, motion.R, motion.t + ray * float(np.linalg.norm(goal)) - goal)


def _outline(mask: np.ndarray) -> np.ndarray | None:
    """The mask's largest outline (OpenCV contour), None where there is none or it touches the image's edge."""
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    outline = max(contours, key=cv2.contourArea)
    x, y, w, h = cv2.boundingRect(outline)
    if x < EDGE_PX or y < EDGE_PX or x + w > mask.shape[1] - EDGE_PX or y + h > mask.shape[0] - EDGE_PX:
        return None
    return outline
