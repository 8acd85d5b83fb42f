"""A block put down keeps the face it stood on down: a goal that turns a block over is turned back by the block's
own half turn.

A block looks the same turned over about a line through the middles of two opposite sides, so the registration of
a block carried elsewhere may settle on that twin: boxes put on a dish and on a scale came out turned 178 deg over
(held-out seeds 8436 and 8640), and every grasp from above was then refused, the hand below the table at the goal.
Putting an object somewhere does not turn it over: when the goal tilts a block's vertical more than TILT_DEG, the
motion is composed with the half turn about one of its horizontal face axes, through its middle, that leaves it
least tilted (the least turn of the two breaking a tie). A block is what no body of revolution is and whose top,
seen whole from above, fills its smallest rectangle; anything else keeps its motion.
"""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.contact.symmetry import ball_centre, revolution_axis
from pipeline.grounding.compare import rotation_deg
from pipeline.grounding.tilt import tilt_deg
from pipeline.grounding.types import ObjectMotion

TILT_DEG = 45.0  # a goal tilting the block's vertical more than this turns it over
TOP_BAND_M = 0.008  # points this close below the highest (percentile 98) are the top face
MIN_TOP_POINTS = 30
RECTANGLE_FILL = 0.9  # a top face filling this much of its smallest rectangle is a rectangle (a disc fills 0.79)


def block_axes(points: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """(middle, first face axis, second face axis) of a block resting with `up` (unit) vertical, the axes horizontal
    and square to its sides; None when the points are no block."""
    if ball_centre(points) is not None or revolution_axis(points) is not None:
        return None
    u = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(up, u)
    height = points @ up
    top = float(np.percentile(height, 98))
    upper = points[height > top - TOP_BAND_M]
    if len(upper) < MIN_TOP_POINTS:
        return None
    flat = np.column_stack([upper @ u, upper @ v]).astype(np.float32)
    (cu, cv), (w, h), angle = cv2.minAreaRect(flat)
    hull = float(cv2.contourArea(cv2.convexHull(flat)))
    if w * h <= 0 or hull < RECTANGLE_FILL * w * h:
        return None
    a = math.radians(angle)
    first = math.cos(a) * u + math.sin(a) * v
    middle = cu * u + cv * v + 0.5 * (top + float(np.percentile(height, 1))) * up
    return middle, first, np.cross(up, first)


def kept_level(motion: ObjectMotion, points_camera: np.ndarray, up_camera: np.ndarray) -> ObjectMotion:
    """The motion (camera frame), turned back by the block's half turn when it would turn a block over."""
    if not motion.ok or len(points_camera) == 0:
        return motion
    up = np.asarray(up_camera, dtype=np.float64) / np.linalg.norm(up_camera)
    if float((motion.R @ up) @ up) > math.cos(math.radians(TILT_DEG)):
        return motion
    axes = block_axes(np.asarray(points_camera, dtype=np.float64), up)
    if axes is None:
        return motion
    middle, *face_axes = axes
    twins = []
    for axis in face_axes:
        H = Rotation.from_rotvec(math.pi * axis).as_matrix()
        R = motion.R @ H
        twins.append((-round(float((R @ up) @ up), 3), rotation_deg(R), R, motion.R @ (middle - H @ middle) + motion.t))
    level, _, R, t = min(twins, key=lambda twin: twin[:2])
    if -level <= float((motion.R @ up) @ up):  # on its side either way: no twin is less tilted
        return motion
    tilt = tilt_deg(motion.R, up)
    why = f"the goal turned the block over ({tilt:.0f} deg): turned back by its half turn, which looks the same"
    return replace(motion, R=R, t=t, details={**motion.details, "kept_level": why})
