"""A goal that turns a block over, put somewhere, is turned back by the block's own half turn; a can, a motion that
keeps the block level, and a tipped block short of over keep their motion (pipeline/grounding/level.py). Camera
frame here = base frame, z up."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.level import kept_level
from pipeline.grounding.types import ObjectMotion

UP = np.array([0.0, 0.0, 1.0])
MIDDLE = np.array([0.5, 0.1, 0.025])


def seen_block(yaw_deg: float, size=(0.05, 0.035, 0.05), n=4000, seed=0) -> np.ndarray:
    """A block's top and the two sides toward the camera (at +x, +y), turned yaw_deg about the vertical."""
    rng = np.random.default_rng(seed)
    half = np.array(size) / 2
    p = rng.uniform(-1, 1, (n, 3)) * half
    face = rng.integers(0, 3, n)
    p[face == 0, 2], p[face == 1, 0], p[face == 2, 1] = half[2], half[0], half[1]
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return p @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T + MIDDLE - [0, 0, 0.025 - half[2]]


def carried(turn: Rotation, to=(0.15, -0.2, 0.02)) -> ObjectMotion:
    """`turn` about the block's middle, then the middle moved by `to`."""
    R = turn.as_matrix()
    return ObjectMotion(True, "", R=R, t=MIDDLE + np.asarray(to) - R @ MIDDLE)


def tilt_deg(R: np.ndarray) -> float:
    return math.degrees(math.acos(np.clip((R @ UP) @ UP, -1, 1)))


def corners(yaw_deg: float, size=(0.05, 0.035, 0.05)) -> np.ndarray:
    half = np.array(size) / 2
    box = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
    return Rotation.from_euler("z", yaw_deg, degrees=True).apply(box) + MIDDLE


@pytest.mark.parametrize("yaw_deg", [0.0, 23.0, -61.0])
@pytest.mark.parametrize("over_deg", [178.0, 120.0])
def test_a_block_turned_over_is_turned_back_onto_the_same_place(yaw_deg, over_deg):
    """Turned back by a half turn about one of its face axes: the goal box is the one the flipped goal fills (a half
    turn about another line would turn it about the vertical as well), its face down."""
    axis = Rotation.from_euler("z", 40.0, degrees=True).apply([1.0, 0.0, 0.0])  # over about some horizontal line
    over = Rotation.from_rotvec(math.radians(over_deg) * axis)
    flipped = carried(Rotation.from_euler("z", 15.0, degrees=True) * over)
    out = kept_level(flipped, seen_block(yaw_deg), UP)
    assert tilt_deg(out.R) == pytest.approx(180.0 - over_deg, abs=1.0)
    goal, twin = corners(yaw_deg) @ flipped.R.T + flipped.t, corners(yaw_deg) @ out.R.T + out.t
    assert np.linalg.norm(twin[:, None] - goal[None], axis=2).min(axis=1).max() < 0.002
    assert "turned the block over" in out.details["kept_level"]


def test_a_level_goal_and_a_can_keep_their_motion():
    level = carried(Rotation.from_euler("z", 70.0, degrees=True))
    assert kept_level(level, seen_block(10.0), UP) is level
    rng = np.random.default_rng(1)
    a, z = rng.uniform(-np.pi / 2, np.pi / 2, 3000), rng.uniform(0, 0.1, 3000)
    can = np.column_stack([0.5 + 0.03 * np.cos(a), 0.1 + 0.03 * np.sin(a), z])  # an upright can's seen half
    flipped = carried(Rotation.from_rotvec([math.pi, 0.0, 0.0]))
    assert kept_level(flipped, can, UP) is flipped
