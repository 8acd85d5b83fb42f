"""A tipped body of revolution's lean toward or away from the camera, read from the goal mask's outline.

A model's goal depth, warped and bled, leaves a tipped body's axis some degrees off in the plane through it and the
camera ray (raycast plates 5-10 deg, cans and bottles 2-6, bowls 2-8): the outline turns the axis about the ray
(silhouette.axis_turned_to_outline) but not toward or away from the camera. How the outline changes with that lean
depends on the body: a plate's ellipse narrows with every degree, a can's outline hardly changes. The body's hull
(its seen slices spun round its axis) is leaned about the line across the goal ray through its middle, and the lean
whose hull lies along the goal outline best is found (outline_fit.py); ground() takes a plate's as found, any other
body's only where the views' geometric agreement does not fall with it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.outline_fit import GoalOutline, refined_angle, turned_about
from pipeline.grounding.umeyama import Similarity

SPAN_DEG, STEP_DEG = 15.0, 1.0  # the leans tried either way, and their step


def leaned_to_outline(
    motion: Similarity, whole: np.ndarray, centre: np.ndarray, direction: np.ndarray, outline: GoalOutline
) -> Similarity:
    """`motion` with the body's axis (`direction`, unit, as at the start) leaned toward or away from the camera, about
    the line across the goal ray through where it puts `centre`, to where the hull of its `whole` (points as at the
    start) lies along the goal outline best; `motion` itself where its axis lies along the ray or no hull is seen."""
    goal = motion.apply(centre[None])[0]
    across = np.cross(goal, motion.R @ direction)
    if np.linalg.norm(across) < 1e-6 * np.linalg.norm(goal):  # seen end on: every lean casts the same outline
        return motion
    across /= np.linalg.norm(across)
    angles = np.radians(np.arange(-SPAN_DEG, SPAN_DEG + 1e-9, STEP_DEG))
    cost = outline.fits(turned_about(motion.apply(whole), goal, across, angles)).cost
    best = int(np.argmin(cost))
    if not np.isfinite(cost[best]):
        return motion
    lean = refined_angle(cost, angles, best)
    return motion.turned_after(Rotation.from_rotvec(lean * across).as_matrix(), goal)
