"""A placed object rests on what is under it: a grounded goal floating above its support or sunk into it is set on it.

The goal image's depth is estimated, not measured, and an object whose pose changes much (a lying can stood up)
is registered against a goal surface it shares little of with its start: the goal may come out centimetres above
the table, in the right place as the camera sees it. The arm then lets it drop from there (a can may topple), and
the achieved pose, resting on the table, is judged off a goal nothing could reach. An object put down, stood up or
turned ends at rest, so its lowest point (of its surface completed where its shape tells the unseen side) is set
REST_GAP_M above the highest scene point beneath it, when it floats more than FLOATING_M above that, or has sunk
into it (the goal's depth a few millimetres low put a box 4 mm into the plate it goes on: held-out seeds 8436 and
8640, every grasp refused as "placed object overlaps the scene"). Nothing beneath it seen (a tall container's
floor, outside the view), or resting already: the goal is kept.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from pipeline.contact.symmetry import completed_points
from pipeline.grounding.types import ObjectMotion

FLOATING_M = 0.01  # a goal this far above its support floats (depth noise and mask edges stay below it)
SUNK_M = 0.01  # scene points up to this far above the goal's bottom may be a support it sank into; higher ones are
# beside it (a bowl's wall, a neighbour)
REST_GAP_M = 0.005  # a settled goal's bottom this far above its support (the contact's placed clearance is 4 mm)
BENEATH_M = 0.01  # scene points within this distance of the goal's footprint (in the plane) are beneath it
BOTTOM_PERCENTILE = 1.0  # the goal's lowest point, robust to a few stray points


def settled(
    motion: ObjectMotion, target_camera: np.ndarray, scene_camera: np.ndarray, up_camera: np.ndarray
) -> ObjectMotion:
    """The motion (camera frame), moved along `up_camera` (unit) to rest on the highest scene point (camera frame,
    the target's own points excluded) beneath the goal when the goal floats above it or has sunk into it."""
    if not motion.ok or len(target_camera) == 0 or len(scene_camera) == 0:
        return motion
    up = np.asarray(up_camera, dtype=np.float64) / np.linalg.norm(up_camera)
    goal = completed_points(target_camera) @ motion.R.T + motion.t
    bottom = float(np.percentile(goal @ up, BOTTOM_PERCENTILE))
    in_plane = np.linalg.svd(up[None], full_matrices=True)[2][1:].T  # two axes across `up`
    below = scene_camera[scene_camera @ up < bottom + SUNK_M]
    if len(below) == 0:
        return motion
    near, _ = cKDTree(goal @ in_plane).query(below @ in_plane, distance_upper_bound=BENEATH_M)
    beneath = np.isfinite(near)
    if not beneath.any():
        return motion
    gap = bottom - float(np.max(below[beneath] @ up))
    if 0.0 <= gap <= FLOATING_M:
        return motion
    if gap > 0.0:
        why = f"the goal floated {gap * 1000:.0f} mm above what is beneath it: lowered onto it"
    else:
        why = f"the goal sank {-gap * 1000:.0f} mm into what is beneath it: raised onto it"
    return replace(motion, t=motion.t - (gap - REST_GAP_M) * up, details={**motion.details, "settled": why})
