"""A goal that shows only part of the object (put into a bowl, its lower part hidden by the wall): the ball's
centre found from the cap that shows, a placement kept where ICP drifts off it, and a fitness that counts how
much of the goal the motion explains."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.grounding.hypotheses import ball_hypotheses
from pipeline.grounding.refine import IcpTarget
from pipeline.grounding.select import _refine
from pipeline.grounding.types import GroundingConfig
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View, make_view

RADIUS = 0.03
CENTRE0, CENTRE1 = np.array([0.10, 0.05, 0.90]), np.array([0.02, 0.07, 0.93])  # camera frame [m]


def seen_sphere(centre: np.ndarray, radius: float, step_m: float = 0.0015) -> np.ndarray:
    """The side of a sphere a camera at the origin looking along +z sees, sampled on a grid of rays."""
    xs = np.arange(centre[0] - radius, centre[0] + radius, step_m)
    ys = np.arange(centre[1] - radius, centre[1] + radius, step_m)
    X, Y = (a.ravel() for a in np.meshgrid(xs, ys))
    dx, dy = X - centre[0], Y - centre[1]
    inside = dx**2 + dy**2 < radius**2
    Z = centre[2] - np.sqrt(np.clip(radius**2 - dx**2 - dy**2, 0, None))
    return np.column_stack([X, Y, Z])[inside]


def seen_box(centre: np.ndarray, half: np.ndarray, step_m: float = 0.0015) -> np.ndarray:
    """The front and top faces of an axis-aligned box (camera y points down)."""
    u = np.arange(-1, 1, step_m / half.min())
    a, b = (g.ravel() for g in np.meshgrid(u, u))
    front = centre + np.column_stack([a * half[0], b * half[1], -np.full_like(a, half[2])])
    top = centre + np.column_stack([a * half[0], -np.full_like(a, half[1]), b * half[2]])
    return np.vstack([front, top])


def view(points: np.ndarray) -> View:
    blank = np.zeros((2, 2))
    return make_view(points, np.zeros_like(points), blank, blank.astype(bool), np.zeros((2, 2, 3)), 0.002)


def above_wall(points: np.ndarray, centre: np.ndarray, hidden_rel: float) -> np.ndarray:
    """What shows over a wall that hides the lower part (camera y down) from hidden_rel radii above the centre."""
    return points[points[:, 1] < centre[1] - hidden_rel * RADIUS]


@pytest.mark.parametrize("hidden_rel", [-1.0, 0.3, 0.5])
def test_a_balls_shift_is_found_from_the_cap_that_shows(hidden_rel):
    goal = above_wall(seen_sphere(CENTRE1, RADIUS), CENTRE1, hidden_rel)
    (motion,) = ball_hypotheses(view(seen_sphere(CENTRE0, RADIUS)), view(goal))
    assert np.linalg.norm(motion.apply(CENTRE0[None])[0] - CENTRE1) < 0.001
    np.testing.assert_allclose(motion.R, np.eye(3))


def test_no_ball_hypothesis_for_a_box_or_a_goal_off_the_ball():
    box = seen_box(CENTRE0, np.array([0.03, 0.02, 0.025]))
    ball = seen_sphere(CENTRE1, RADIUS)
    assert ball_hypotheses(view(box), view(ball)) == []
    assert ball_hypotheses(view(seen_sphere(CENTRE0, RADIUS)), view(seen_box(CENTRE1, np.full(3, 0.03)))) == []


def test_a_placement_icp_drifts_off_is_kept_and_counted_by_how_much_of_the_goal_it_explains():
    """Point-to-plane ICP on a sphere is free to spin about its centre and here drifts off altogether (no point
    left within reach); the exact shift is kept, and its fitness is the share of the goal's cap it explains, not
    the small share of the capture's front that the cap covers."""
    source = view(seen_sphere(CENTRE0, RADIUS))
    goal = view(above_wall(seen_sphere(CENTRE1, RADIUS), CENTRE1, 0.5))
    target = IcpTarget(goal.cloud, goal.normals)
    exact = Similarity(1.0, np.eye(3), CENTRE1 - CENTRE0)
    size = float(np.linalg.norm(np.percentile(source.cloud, 95, axis=0) - np.percentile(source.cloud, 5, axis=0)))
    cfg = GroundingConfig()
    T0 = np.eye(4)
    T0[:3, 3] = exact.t
    assert target.refine(source.cloud, T0, cfg.icp_max_corr_rel * size).fitness < 0.3  # what ICP alone gives
    kept = _refine(exact, source.cloud, target, size, cfg)
    assert kept is not None
    motion, fitness = kept
    assert np.linalg.norm(motion.apply(CENTRE0[None])[0] - CENTRE1) < 0.001
    assert fitness > 0.9
