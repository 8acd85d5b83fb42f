"""A bottle stands on its base: a grounded motion that would stand one on its neck is turned end for end, and one
that would stand it leaning is stood straight.

The registration of a bottle seen lying, its neck small in the view, may settle on either end up (the seen sides of
the two ends differ by a few pixels of neck); the contact then stands it on its neck, where it lands off its goal or
topples. A body of revolution whose ends differ (its slices' radii along the seen length: a bottle's neck) has a wide
end, its base; when the goal leaves its axis within STANDING_DEG of vertical with that end up, the motion composed
with a half turn across the axis about the axis's middle puts the base down and the centre where it was. A can (one
radius all along) and anything else keep their motion.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from pipeline.contact.symmetry import RevolutionAxis, revolution_axis, slice_radii
from pipeline.grounding.compare import half_turn_across
from pipeline.grounding.types import ObjectMotion
from safety.geometry import turn_about

STANDING_DEG = 45.0  # a goal axis this close to vertical stands the object
WIDE_REL = 0.15  # one end's slices this much wider than the other's: the wide end is its base
MIN_LEAN_DEG = 2.0  # a goal axis leaning less than this off vertical is left (the axis fit's own error)


def wide_end(points: np.ndarray, axis: RevolutionAxis) -> np.ndarray | None:
    """The unit direction along the axis toward the wider end of the seen body (its base), or None when the ends'
    radii (the median radius of the slices in each third of the seen length) are within WIDE_REL of each other."""
    s, radii = slice_radii(points, axis.point, axis.direction)
    if len(radii) < 3:
        return None
    third = (s.max() - s.min()) / 3
    low = float(np.median(radii[s <= s.min() + third]))
    high = float(np.median(radii[s >= s.max() - third]))
    if abs(low - high) <= WIDE_REL * max(low, high):
        return None
    return -axis.direction if low > high else axis.direction


def stood_on_its_base(motion: ObjectMotion, points_camera: np.ndarray, up_camera: np.ndarray) -> ObjectMotion:
    """The motion (camera frame), turned end for end when it would stand the object on its narrow end."""
    if not motion.ok:
        return motion
    axis = revolution_axis(points_camera)
    if axis is None or axis.ends_alike:
        return motion
    base = wide_end(points_camera, axis)
    if base is None or float((motion.R @ base) @ up_camera) < math.cos(math.radians(STANDING_DEG)):
        return motion  # not standing, or standing on its base
    H = half_turn_across(axis.direction)
    R = motion.R @ H
    t = motion.R @ (axis.point - H @ axis.point) + motion.t
    why = "the goal stood it on its narrow end: turned end for end to stand on its base"
    return replace(motion, R=R, t=t, details={**motion.details, "turned_end_for_end": why})


def stood_straight(motion: ObjectMotion, points_camera: np.ndarray, up_camera: np.ndarray) -> ObjectMotion:
    """The motion (camera frame) turned about the goal axis's middle so that the body of revolution it stands up
    stands straight: a bottle set down leaning falls onto its base, off the goal (a goal grounded 13.7 deg off
    vertical put a stood-up bottle 31 mm from where it said, and the run took its leaning goal as achieved). Kept
    when the object is no body of revolution or the goal does not stand it (axis over STANDING_DEG from vertical)."""
    if not motion.ok:
        return motion
    axis = revolution_axis(points_camera)
    if axis is None:
        return motion
    goal_axis = motion.R @ axis.direction
    goal_axis = goal_axis if goal_axis @ up_camera >= 0 else -goal_axis
    lean = math.degrees(math.acos(float(np.clip(goal_axis @ up_camera, -1.0, 1.0))))
    if lean > STANDING_DEG or lean < MIN_LEAN_DEG:
        return motion
    turn = np.cross(goal_axis, up_camera)
    middle = motion.R @ axis.point + motion.t
    T = turn_about(middle, turn / np.linalg.norm(turn), math.radians(lean))
    R, t = T[:3, :3] @ motion.R, T[:3, :3] @ motion.t + T[:3, 3]
    why = f"the goal leaned the body's axis {lean:.1f} deg off vertical: stood straight"
    return replace(motion, R=R, t=t, details={**motion.details, "stood_straight": why})
