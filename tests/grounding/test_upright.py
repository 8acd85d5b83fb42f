"""A bottle stands on its base: a grounded motion standing one on its neck is turned end for end, one standing it
on its base and a can's are kept; one standing it leaning is stood straight."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.types import ObjectMotion
from pipeline.grounding.upright import stood_on_its_base, stood_straight

UP = np.array([0.0, 0.0, 1.0])  # camera frame == base frame here
CENTRE = np.array([0.45, 0.0, 0.03])


def lying(neck: bool, n: int = 5000, seed: int = 0) -> np.ndarray:
    """The upper half of a body lying along +x: a 3 cm radius body 13 cm long, then (a bottle) a 1.2 cm neck 5 cm
    long at +x; 0.5 mm noise."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-0.09, 0.09, n)
    radius = np.where(x > 0.04, 0.012, 0.03) if neck else np.full(n, 0.03)
    angle = rng.uniform(-np.pi / 2, np.pi / 2, n)
    points = CENTRE + np.column_stack([x, radius * np.sin(angle), radius * np.cos(angle)])
    return points + rng.normal(0, 0.0005, points.shape)


def standing(neck_up: bool) -> ObjectMotion:
    """A quarter turn about y through the centre: +x (the neck's end) ends up, or down."""
    R = Rotation.from_euler("y", -90 if neck_up else 90, degrees=True).as_matrix()
    return ObjectMotion(ok=True, reason="", R=R, t=CENTRE - R @ CENTRE + np.array([0.0, 0.1, 0.06]))


def test_a_bottle_stood_on_its_neck_is_turned_end_for_end_about_its_middle():
    points = lying(neck=True)
    motion = stood_on_its_base(standing(neck_up=False), points, UP)
    assert "turned_end_for_end" in motion.details
    neck = np.array([1.0, 0.0, 0.0])
    assert (motion.R @ neck) @ UP > 0.99  # the neck end now up
    middle = np.array([CENTRE[0] + 0.0, 0.0, CENTRE[2]])
    before = standing(neck_up=False)
    moved = lambda m, p: m.R @ p + m.t  # noqa: E731
    assert np.linalg.norm(moved(motion, middle) - moved(before, middle)) < 0.02  # lands where the goal put it


@pytest.mark.parametrize(("neck", "neck_up"), [(True, True), (False, False), (False, True)])
def test_a_bottle_on_its_base_and_a_can_either_way_keep_their_motion(neck, neck_up):
    given = standing(neck_up)
    motion = stood_on_its_base(given, lying(neck=neck), UP)
    assert "turned_end_for_end" not in motion.details
    np.testing.assert_array_equal(motion.R, given.R)


def test_a_bottle_left_lying_keeps_its_motion():
    shift = ObjectMotion(ok=True, reason="", R=np.eye(3), t=np.array([0.1, 0.0, 0.0]))
    assert stood_on_its_base(shift, lying(neck=True), UP) is shift


@pytest.mark.parametrize("lean_deg", [13.7, -30.0])
def test_a_stand_up_goal_leaning_off_vertical_is_stood_straight_about_its_middle(lean_deg):
    """A goal grounded 13.7 deg off vertical (held-out case 13062): the bottle set down leaning falls onto its base
    off the goal; stood straight, the axis is vertical and its middle stays where the goal put it."""
    points = lying(neck=True)
    given = standing(neck_up=True)
    lean = Rotation.from_euler("x", lean_deg, degrees=True).as_matrix()
    middle = np.array([CENTRE[0], 0.0, CENTRE[2]])  # on the body's axis
    goal_middle = given.R @ middle + given.t
    leaning = ObjectMotion(ok=True, reason="", R=lean @ given.R, t=lean @ (given.t - goal_middle) + goal_middle)
    motion = stood_straight(leaning, points, UP)
    assert "stood_straight" in motion.details
    axis = np.array([1.0, 0.0, 0.0])
    assert (motion.R @ axis) @ UP > 0.9999  # the neck end straight up
    axis_middle = np.array([0.0 + CENTRE[0], 0.0, CENTRE[2]])
    assert np.linalg.norm((motion.R @ axis_middle + motion.t) - goal_middle) < 0.005


def test_a_straight_stand_up_and_a_move_that_leaves_the_body_lying_keep_their_motion():
    upright = standing(neck_up=True)
    assert stood_straight(upright, lying(neck=True), UP) is upright
    shift = ObjectMotion(ok=True, reason="", R=np.eye(3), t=np.array([0.1, 0.0, 0.0]))
    assert stood_straight(shift, lying(neck=True), UP) is shift
