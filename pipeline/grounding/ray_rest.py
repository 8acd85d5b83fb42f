"""The goal's distance along the camera ray, from what the object rests on.

A model's goal depth is aligned on the background, but under the object it can still be centimetres off (a local
warp the background does not show): the object then comes out where the goal image shows it, too near or too far
along the ray through it, floating above its support or sunk into it. An object that rested on what was beneath
it, and is slid or turned about the vertical, stands above what is beneath its goal as it stood at the start: each
of its points keeps its height above the support. So the goal is moved along the ray through it, which keeps it
where the image shows it, until its seen points' middle stands as high above the support beneath the goal as it
stood above the one beneath the start. The supports are read in the capture's measured depth, not in the model's.
A tipped object, one that did not rest at the start (held, or on something unseen), one with nothing seen beneath
its goal or nothing level there (the inside of a bowl), or a correction too large to be depth error (put on
something else): left as it is. A tipped body is only raised out of the table where its goal sinks into it
(out_of_support), or set down on it where its whole shape is known (set_down).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.compare import sphere_directions
from pipeline.grounding.settle import beneath
from pipeline.grounding.tilt import tilt_deg
from pipeline.grounding.umeyama import Similarity

UPRIGHT_DEG = 10.0  # the motion tilts the vertical less than this: its points keep their heights
SPUN_UPRIGHT_DEG = 2.0  # a level twin spun about the body's axis still tilting more: the axis is read too poorly
# for its seen points' heights (MuJoCo bottles lying: 3.7-7.9 deg, rested 4-16 mm wrong; raycast ones 0.5-1.0 deg)
LOWEST_PERCENTILE = 1.0  # an object's lowest point, robust to a few stray points
RESTED_M = 0.015  # at the start, its lowest seen point within this of a support beneath: it rested there
MAX_SHIFT_M = 0.03  # a correction of the height above the support beyond this is not depth error ...
MIN_GAP_M = 0.002  # ... and under this it is within what the heights are read to (a sensor's noise on the support)
MIN_RAY_SLOPE = 0.2  # a ray this close to horizontal hardly changes height along it
BENEATH_M = 0.02  # scene points within this of the object's footprint (across the vertical) are beneath it
MIN_SUPPORT_POINTS = 20
SET_DOWN_REACH_M = 0.05  # a goal set down looks for the table this far above or below its lowest point
SINK_TOLERANCE_M = 0.003  # a body's lowest point read from its seen points: 1 % of raycast truths 3.3 mm under
BOTTOM_SLICE_M = 0.005  # the bottom of a body copied down onto what it rested on
LEVEL_SPREAD_M = 0.01  # a support's heights beneath spread this much at most (p10-p90; a table read 1-4 mm)


def rest_along_ray(
    motion: Similarity,
    cloud0: np.ndarray,
    scene0: np.ndarray,
    up: np.ndarray,
    min_gap_m: float = MIN_GAP_M,
    through: np.ndarray | None = None,
    spin: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[Similarity, float]:
    """(the motion moved along the camera ray through its goal so that the object stands above the support
    beneath its goal as it stood above the one beneath it at the start, the shift along the ray [m]), or (the
    motion, 0) where that cannot be told. `cloud0` (N, 3): the object's seen points at the start, or its whole
    body where that is known (a ball: its seen points stop near the equator, too high to find the table beneath);
    `scene0` (M, 3): the capture's other points (the object's own left out); `up` (3,): the table normal; all camera
    frame. `min_gap_m`: corrections smaller than this are left (0 for a whole body: a ball's centre is read to a
    fraction of a millimetre, its seen points' middle through ICP is not). `through` (3,): the point, as at the
    start, whose ray the goal moves along, where its place across the ray is known (a body of revolution's axis
    set in its outline's plane of symmetry, silhouette.py); the points' middle by default. `spin` ((3,), (3,)): a
    point on a body of revolution's axis and the axis, as at the start: the motion is judged by its twin spun about
    it that tilts the vertical least (a bottle lying on its side, slid, may come out spun 25 deg about its own axis:
    the same body in the same place, its seen points at other heights)."""
    up = up / np.linalg.norm(up)
    upright = motion
    if tilt_deg(motion.R, up) > UPRIGHT_DEG:  # tipped, unless a level twin with its axis read well enough
        if spin is None:
            return motion, 0.0
        upright = least_tilting_spin(motion, spin[1], spin[0], up)
        if tilt_deg(upright.R, up) > SPUN_UPRIGHT_DEG:
            return motion, 0.0
    start = height_above_support(cloud0, scene0, up, RESTED_M)
    if start is None:  # nothing beneath it within RESTED_M: it did not rest
        return motion, 0.0
    goal = upright.apply(cloud0)
    now = height_above_support(goal, scene0, up, MAX_SHIFT_M)
    if now is None or not min_gap_m <= abs(now - start) <= MAX_SHIFT_M:
        return motion, 0.0
    ray = goal.mean(axis=0) if through is None else motion.apply(through[None])[0]
    ray /= np.linalg.norm(ray)
    if abs(ray @ up) < MIN_RAY_SLOPE:
        return motion, 0.0
    shift = -(now - start) / float(ray @ up)
    return Similarity(motion.scale, motion.R, motion.t + shift * ray), shift


def least_tilting_spin(motion: Similarity, axis: np.ndarray, point: np.ndarray, up: np.ndarray) -> Similarity:
    """`motion` after the body is first spun about its own `axis` (through `point`, as at the start, camera frame) by
    the angle that leaves the vertical `up` (unit) tilted least: f(a) = up . R S(a) up is A cos a + B sin a + const."""
    a = axis / np.linalg.norm(axis)
    across = up - (up @ a) * a
    A, B = up @ motion.R @ across, up @ motion.R @ np.cross(a, across)
    return motion.turned_first(Rotation.from_rotvec(float(np.arctan2(B, A)) * a).as_matrix(), point)


def ball_surface(centre: np.ndarray, radius: float, count: int = 256) -> np.ndarray:
    """(count, 3) points spread evenly over a ball's whole surface (a Fibonacci lattice): the body rest_along_ray
    sets on its support where the seen points stop near the ball's equator."""
    return centre + radius * sphere_directions(count)


def height_above_support(points: np.ndarray, scene: np.ndarray, up: np.ndarray, reach: float) -> float | None:
    """How far the points' middle stands above the scene beneath them (the median height of the scene points under
    their footprint within `reach` of their lowest either way: the highest of them would be the noisiest), None
    when nothing is seen there or it is not level (LEVEL_SPREAD_M). The middle, not the lowest: a motion a few
    degrees off tilts a wide object's lowest point by centimetres, its middle hardly."""
    lowest = float(np.percentile(points @ up, LOWEST_PERCENTILE))
    level = scene[np.abs(scene @ up - lowest) <= reach]
    heights = level[beneath(points, level, up, BENEATH_M)] @ up
    if len(heights) < MIN_SUPPORT_POINTS or np.ptp(np.percentile(heights, [10, 90])) > LEVEL_SPREAD_M:
        return None  # nothing seen beneath, or no one level to stand on (the inside of a bowl)
    return float(np.mean(points @ up)) - float(np.median(heights))


def set_down(
    motion: Similarity, body: np.ndarray, middle: np.ndarray, scene0: np.ndarray, up: np.ndarray
) -> Similarity | None:
    """`motion` moved along the camera ray through the body's goal `middle` until its lowest point (of the whole
    `body`, as at the start) touches the level scene beneath it; None where nothing level is seen there or the ray
    hardly changes height."""
    gap = _goal_gap(motion, body, scene0, up)
    return None if gap is None else _raised(motion, middle, up, -gap)


def out_of_support(
    motion: Similarity, body: np.ndarray, middle: np.ndarray, scene0: np.ndarray, up: np.ndarray
) -> Similarity:
    """`motion` raised along the camera ray through the body's goal `middle` until its lowest point (of `body`, as
    at the start) sinks no more than SINK_TOLERANCE_M into the level scene beneath it; as it is where it does not
    sink or nothing level is seen there. A body read from its seen points can miss a part that hangs lower, never
    add one: it may come out floating above its support, but where it sinks into it the model's depth put it too
    far along the ray (raycast goals tipped onto a side came out 10-40 mm far, their bodies 5-20 mm in the table)."""
    gap = _goal_gap(motion, body, scene0, up)
    if gap is None or gap >= -SINK_TOLERANCE_M:
        return motion
    return _raised(motion, middle, up, -gap - SINK_TOLERANCE_M) or motion


def down_to_support(body: np.ndarray, scene0: np.ndarray, up: np.ndarray) -> np.ndarray:
    """`body` (N, 3, the capture's seen or whole points) with its lowest BOTTOM_SLICE_M copied down onto the support
    it rested on (within RESTED_M beneath it): what stands on a table reaches down to it, while its seen points
    stop above (cut at the support, seen_symmetry.SUPPORT_CLEARANCE_M, or hidden under it); as it is where it did
    not rest."""
    heights = body @ up
    lowest = float(np.percentile(heights, LOWEST_PERCENTILE))
    above = height_above_support(body, scene0, up, RESTED_M)
    gap = None if above is None else above - (float(np.mean(heights)) - lowest)
    if gap is None or not 0.0 < gap <= RESTED_M:
        return body
    return np.vstack([body, body[heights <= lowest + BOTTOM_SLICE_M] - gap * up])


def _goal_gap(motion: Similarity, body: np.ndarray, scene0: np.ndarray, up: np.ndarray) -> float | None:
    """How far [m] the body's lowest point at the goal stands above the level scene beneath it (negative: sunk),
    None where nothing level is seen there."""
    goal = motion.apply(body)
    above = height_above_support(goal, scene0, up, SET_DOWN_REACH_M)  # of the goal's middle height
    if above is None:
        return None
    return above - (float(np.mean(goal @ up)) - float(np.percentile(goal @ up, LOWEST_PERCENTILE)))


def _raised(motion: Similarity, middle: np.ndarray, up: np.ndarray, rise: float) -> Similarity | None:
    """`motion` moved along the camera ray through the goal of `middle` (as at the start) by what raises it `rise`
    [m]; None where the ray hardly changes height."""
    ray = motion.apply(middle[None])[0]
    ray /= np.linalg.norm(ray)
    if abs(ray @ up) < MIN_RAY_SLOPE:
        return None
    return Similarity(motion.scale, motion.R, motion.t + rise / float(ray @ up) * ray)
