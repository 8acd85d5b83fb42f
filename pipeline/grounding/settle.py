"""A placed object rests on what is under it: a grounded goal floating above its support or sunk into it is set on it.

The goal image's depth is estimated, not measured, and an object whose pose changes much (a lying can stood up)
is registered against a goal surface it shares little of with its start: the goal may come out centimetres above
the table, in the right place as the camera sees it. The arm then lets it drop from there (a can may topple), and
the achieved pose, resting on the table, is judged off a goal nothing could reach. An object put down, stood up or
taken off ends at rest, so its lowest point (of its surface completed where its shape tells the unseen side) is set
REST_GAP_M above the highest scene point beneath it, when it floats more than FLOATING_M above that, or has sunk
into it (the goal's depth a few millimetres low put a box 4 mm into the plate it goes on: held-out seeds 8436 and
8640, every grasp refused as "placed object overlaps the scene"), or below the table (a bottle stood up 39 mm into
it, seed 8802). Nothing beneath it seen (a tall container's floor, outside the view), or resting already: the
goal is kept. The verification settles the achieved motion the same way: an object at rest after the run rests
on something, and a registration between a lying and a standing bottle slides along the axis they hardly share.
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
    motion: ObjectMotion,
    target_camera: np.ndarray,
    scene_camera: np.ndarray,
    up_camera: np.ndarray,
    table_height: float | None = None,
) -> ObjectMotion:
    """The motion (camera frame), moved along `up_camera` (unit) to rest on the highest scene point (camera frame,
    the target's own points excluded) beneath the goal when the goal floats above it or has sunk into it, and
    onto the table (its height along `up_camera`, when given) when it has sunk below it: nothing rests under the
    table, though a goal over a container's unseen floor may float above it."""
    if not motion.ok or len(target_camera) == 0:
        return motion
    up = np.asarray(up_camera, dtype=np.float64) / np.linalg.norm(up_camera)
    goal = completed_points(target_camera) @ motion.R.T + motion.t
    bottom = float(np.percentile(goal @ up, BOTTOM_PERCENTILE))
    support = _support(goal, bottom, np.asarray(scene_camera, dtype=np.float64).reshape(-1, 3), up)
    floor = max(x for x in (support, table_height, -np.inf) if x is not None)
    if support is not None and bottom - support > FLOATING_M:
        gap = bottom - support
        why = f"the goal floated {gap * 1000:.0f} mm above what is beneath it: lowered onto it"
    elif bottom < floor:
        gap = bottom - floor
        what = "the table" if support is None or floor > support else "what is beneath it"
        why = f"the goal sank {-gap * 1000:.0f} mm into {what}: raised onto it"
    else:
        return motion
    return replace(motion, t=motion.t - (gap - REST_GAP_M) * up, details={**motion.details, "settled": why})


def _support(goal: np.ndarray, bottom: float, scene: np.ndarray, up: np.ndarray) -> float | None:
    """Height of the highest scene point beneath the goal's footprint, up to SUNK_M above its bottom; None if none."""
    below = scene[scene @ up < bottom + SUNK_M]
    under = below[beneath(goal, below, up, BENEATH_M)]
    return float(np.max(under @ up)) if len(under) else None


def beneath(points: np.ndarray, scene: np.ndarray, up: np.ndarray, within_m: float) -> np.ndarray:
    """(M,) whether each scene point lies within `within_m` of the points' footprint, across `up` (unit)."""
    across = np.linalg.svd(up[None], full_matrices=True)[2][1:].T  # two axes across `up`
    flat, scene_flat = points @ across, scene @ across
    lo, hi = flat.min(axis=0) - within_m, flat.max(axis=0) + within_m
    inside = (scene_flat >= lo) & (scene_flat <= hi)
    boxed = np.flatnonzero(inside[:, 0] & inside[:, 1])  # the tree only for these (all(axis=1): 3.2 vs 2.4 ms a call)
    out = np.zeros(len(scene), dtype=bool)
    if len(boxed):
        gap, _ = cKDTree(flat).query(scene_flat[boxed], distance_upper_bound=within_m)
        out[boxed[np.isfinite(gap)]] = True
    return out
