"""A flat body of revolution tipped up in the goal, from the ellipse its outline makes.

A plate tipped onto its rim shows the camera its other face or its edge, and a model's depth of it is poor: the
hypotheses that the features and the sweep give keep its seen face toward the camera, and none of them explains the
views (raycast plates tipped 20-90 deg were refused at view agreements of 0.21-0.29, the true motion's 0.73-0.82).
Its outline does not depend on that depth. A disc casts an ellipse whose short axis over its long one is the cosine
of the disc's tilt from the line of sight, the short axis lying along the disc's axis as the image shows it, and
whose long axis is the disc's width. That leaves four tilts (toward or away from the camera, either face first);
the one whose agreement over all points (Agreement.whole) is best is set down on the table beneath it (the goal
rests on its rim), refined by ICP and set down again.

A plate seen from above (is_plate) has its lean toward or away from the camera read off its goal outline as found
(lean_outline.py): its ellipse narrows with every degree of it.
"""

from __future__ import annotations

import cv2
import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.contact.symmetry import revolved, slice_radii
from pipeline.grounding.compare import turns_onto
from pipeline.grounding.ray_rest import set_down
from pipeline.grounding.select import Selected, fine_tolerance, select_motion
from pipeline.grounding.silhouette import largest_outline
from pipeline.grounding.types import GroundingConfig
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View, view_evidences

FLAT_REL = 0.3  # seen along its axis less than this share of its width: flat (a plate; a bowl is not)
# a plate's outline shows its lean, a bowl's less: seen along their axes raycast plates span 0.05-0.10 of their
# width, bowls 0.20-0.30 (their outline read leans 2-3 deg off where the depth had them right) ...
PLATE_REL = 0.15
# ... and a plate seen from above shows its face: most of its seen surface faces within 45 deg of its axis (raycast
# plates: median 0.75-0.95 of it), not the end of a can lying on its side read as standing (0.64; leaned 4 deg off)
FACING_COS = float(np.cos(np.radians(45.0)))


def is_flat(seen0: np.ndarray, point: np.ndarray, direction: np.ndarray, rel: float = FLAT_REL) -> bool:
    """Whether the body of revolution (its seen points, a point on its axis and the axis's unit direction) is seen
    along its axis for less than `rel` of its width."""
    return _flat(*slice_radii(seen0, point, direction), rel)


def _flat(heights: np.ndarray, radii: np.ndarray, rel: float) -> bool:
    """Whether slices at `heights` along an axis with `radii` span less than `rel` of their width along it."""
    return len(radii) > 0 and np.ptp(heights) < rel * 2.0 * radii.max()


def is_plate(seen0: tuple[np.ndarray, np.ndarray], point: np.ndarray, direction: np.ndarray) -> bool:
    """Whether a body of revolution (its seen points and their normals, a point on its axis and the axis's unit
    direction) is a plate seen from above (PLATE_REL, FACING_COS)."""
    points, normals = seen0
    return is_flat(points, point, direction, PLATE_REL) and float(np.median(np.abs(normals @ direction))) >= FACING_COS


def tipped_disc(
    view0: View,
    view1: View,
    K: CameraIntrinsics,
    size: float,
    cfg: GroundingConfig,
    axis: tuple[np.ndarray, np.ndarray],
    seen0: np.ndarray,
    scene0: np.ndarray,
    up: np.ndarray,
    mask1: np.ndarray,
) -> Selected | None:
    """The motion that stands the flat body of revolution (`axis`: a point on its axis and its direction, `seen0`:
    its seen points, all as at the start, camera frame) where the goal mask's ellipse shows it, resting on the table
    (`scene0`: the capture's other points, `up`: the table's normal); None where it is not flat, the outline is cut,
    or nothing level is seen beneath it."""
    point, direction = axis[0], axis[1] / np.linalg.norm(axis[1])
    heights, radii = slice_radii(seen0, point, direction)
    if not _flat(heights, radii, FLAT_REL):
        return None
    middle = point + 0.5 * (heights.min() + heights.max()) * direction
    tilts = _disc_tilts(mask1, K, middle, direction, 2.0 * float(radii.max()))
    if not tilts:
        return None
    fine = fine_tolerance(size, cfg)
    whole = [agreement.whole for agreement, _ in view_evidences(tilts, view0, view1, K, fine)]
    body, up = revolved(seen0, point, direction), up / np.linalg.norm(up)
    down = set_down(tilts[int(np.argmax(whole))], body, middle, scene0, up)
    if down is None:
        return None
    refined = select_motion([down], view0, view1, K, size, cfg)
    again = set_down(refined.motion, body, middle, scene0, up) or refined.motion
    agreement = view_evidences([again], view0, view1, K, fine)[0][0]
    return Selected(again, agreement, refined.fitness)


def _disc_tilts(
    mask1: np.ndarray, K: CameraIntrinsics, middle: np.ndarray, direction: np.ndarray, width: float
) -> list[Similarity]:
    """The four motions that carry the disc (its `middle` and axis `direction`, as at the start; `width` [m]) to
    where the ellipse fitted to the goal mask's outline shows it: its centre on the ray through the ellipse's, as far
    as the long axis makes its width, its axis tilted either way about the long axis, either face first."""
    outline = largest_outline(mask1)
    if outline is None or len(outline) < 5:
        return []
    (u, v), (a, b), angle = cv2.fitEllipse(outline)
    long_px, short_px = max(a, b), min(a, b)
    if not short_px > 0.0:  # a line of pixels: no ellipse
        return []
    across = np.radians(angle) + (0.0 if a < b else np.pi / 2)  # OpenCV's angle is that of the side of length a
    goal = K.unproject(np.array([[u, v]]), np.array([K.fx * width / long_px]))[0]
    ray = goal / np.linalg.norm(goal)
    short = np.array([np.cos(across), np.sin(across), 0.0])
    short -= (short @ ray) * ray  # the short axis as a direction across the ray
    short /= np.linalg.norm(short)
    cos = short_px / long_px
    sin = np.sqrt(max(0.0, 1.0 - cos * cos))
    normals = [face * (-cos * ray + lean * sin * short) for face in (1.0, -1.0) for lean in (1.0, -1.0)]
    return [Similarity(1.0, R, goal - R @ middle) for R in turns_onto(direction, np.array(normals))]
