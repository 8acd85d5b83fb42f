"""A goal that leaves a placed object floating above what is beneath it, or sunk into it, is set on it; one at
rest, or over nothing seen, is kept (pipeline/grounding/settle.py). Camera frame here = base frame, z up."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.grounding.settle import REST_GAP_M, settled
from pipeline.grounding.types import ObjectMotion

UP = np.array([0.0, 0.0, 1.0])
RADIUS, LENGTH = 0.03, 0.12


def lying_can_seen_from_above(n: int = 3000, seed: int = 0) -> np.ndarray:
    """The upper half of a can lying along x on the table (axis at z = RADIUS), centred at (0.5, 0)."""
    rng = np.random.default_rng(seed)
    a, x = rng.uniform(0, np.pi, n), rng.uniform(-LENGTH / 2, LENGTH / 2, n)
    return np.column_stack([0.5 + x, RADIUS * np.cos(a), RADIUS + RADIUS * np.sin(a)])


def table(z: float = 0.0, centre=(0.5, 0.0), half: float = 0.2, step: float = 0.004) -> np.ndarray:
    g = np.arange(-half, half, step)
    X, Y = np.meshgrid(centre[0] + g, centre[1] + g)
    return np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, z)])


def stand_up(rest_at: float, to=(0.55, 0.05)) -> ObjectMotion:
    """Turn the can's axis from x to z about its centre, then put its centre at `to`, its bottom at `rest_at`."""
    R = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # x -> z
    centre = np.array([0.5, 0.0, RADIUS])
    goal_centre = np.array([to[0], to[1], rest_at + LENGTH / 2])
    return ObjectMotion(True, "", R=R, t=goal_centre - R @ centre)


def bottom(motion: ObjectMotion, can: np.ndarray) -> float:
    """The goal's lowest point, the can's full surface (both halves) moved."""
    full = np.vstack([can, can * [1, -1, -1] + [0, 0, 2 * RADIUS]])
    return float(np.min((full @ motion.R.T + motion.t) @ UP))


def without_the_can(scene: np.ndarray) -> np.ndarray:
    """The table as the camera sees it: not where the can lies now (its own mask)."""
    return scene[np.hypot(scene[:, 0] - 0.5, scene[:, 1]) > 0.07]


def test_a_can_stood_up_floating_above_the_table_is_set_on_it():
    can = lying_can_seen_from_above()
    floating = stand_up(rest_at=0.035)
    out = settled(floating, can, without_the_can(table()), UP)
    assert bottom(out, can) == pytest.approx(REST_GAP_M, abs=0.003)
    np.testing.assert_allclose(out.t[:2], floating.t[:2])  # where the camera put it, only lower
    np.testing.assert_allclose(out.R, floating.R)
    assert "lowered onto it" in out.details["settled"]


def test_a_goal_over_a_plate_rests_on_the_plate():
    can = lying_can_seen_from_above()
    plate = table(z=0.015, centre=(0.55, 0.05), half=0.06)
    scene = np.vstack([without_the_can(table()), plate])
    out = settled(stand_up(rest_at=0.05), can, scene, UP)
    assert bottom(out, can) == pytest.approx(0.015 + REST_GAP_M, abs=0.003)


def test_a_goal_sunk_into_a_plate_is_raised_onto_it():
    """The goal's depth a few millimetres low: the object would overlap the plate it is put on."""
    can = lying_can_seen_from_above()
    plate = table(z=0.015, centre=(0.55, 0.05), half=0.06)
    scene = np.vstack([without_the_can(table()), plate])
    motion = stand_up(rest_at=0.011)
    out = settled(motion, can, scene, UP)
    assert bottom(out, can) == pytest.approx(0.015 + REST_GAP_M, abs=0.003)
    np.testing.assert_allclose(out.t[:2], motion.t[:2])
    assert "raised onto it" in out.details["settled"]


@pytest.mark.parametrize("rest_at", [0.0, 0.006])
def test_a_goal_at_rest_is_kept(rest_at):
    can = lying_can_seen_from_above()
    motion = stand_up(rest_at=rest_at)
    out = settled(motion, can, without_the_can(table()), UP)
    assert out is motion


def test_a_goal_over_nothing_seen_is_kept():
    can = lying_can_seen_from_above()
    far_table = table(centre=(0.9, 0.5), half=0.05)
    motion = stand_up(rest_at=0.04)
    assert settled(motion, can, far_table, UP) is motion


def test_a_goal_sunk_below_the_table_is_raised_onto_it_though_no_table_is_seen_beneath_it():
    """The can stood up where it lay: the table beneath its goal was hidden by the can itself in the capture. The
    table's own height (the base frame's z = 0) still holds it up; without it the goal would be kept."""
    can = lying_can_seen_from_above()
    sunk = stand_up(rest_at=-0.039, to=(0.5, 0.0))
    scene = without_the_can(table())
    out = settled(sunk, can, scene, UP, table_height=0.0)
    assert bottom(out, can) == pytest.approx(REST_GAP_M, abs=0.003)
    assert "into the table" in out.details["settled"]
    assert settled(sunk, can, scene, UP) is sunk


def test_a_goal_floating_over_no_seen_floor_is_not_lowered_to_the_table():
    """Over a tall container's unseen floor: the table only holds a goal up, never pulls it down."""
    can = lying_can_seen_from_above()
    motion = stand_up(rest_at=0.04)
    assert settled(motion, can, table(centre=(0.9, 0.5), half=0.05), UP, table_height=0.0) is motion
