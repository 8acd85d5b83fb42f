"""A box's turn about the vertical, read from the goal mask's outline.

A model's goal depth tilts a small box's faces by 5-10 deg (its edges bled into what lies behind them, the noise
smoothed over that bleed, a slow warp left under it), and the registration follows: boxes standing on the table came
out turned 6-25 deg about the vertical from where the goal image shows them (raycast pairs). The outline does not
depend on that depth. A box's outline is the convex hull of its eight corners' images: the capture's measured points
give the box (seen_symmetry.seen_box), the motion carries it to the goal, and of its turns about the vertical through
its goal centre the one is taken whose hull lies along the goal mask's outline best (outline_fit.py).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.outline_fit import GoalOutline, parabola_vertex
from pipeline.grounding.seen_symmetry import SeenBox
from pipeline.grounding.umeyama import Similarity

SPAN_DEG, STEP_DEG = 30.0, 1.0  # turns tried either way about the vertical, and their step
MIN_ALONG = 0.7  # the hull's share along the outline at its best turn: less, and the outline is not this box's
# a hull drawn from seen points and a ragged outline tell a turn to a degree or two: a smaller one is left to the
# depth (MuJoCo boxes, their goal depth good to 0.2 %, came out 0.1 -> 1.3 deg off)
MIN_TURN_DEG = 2.0


def turned_to_outline(motion: Similarity, box: SeenBox, up: np.ndarray, outline: GoalOutline) -> Similarity:
    """`motion` turned about the vertical `up` (unit, camera frame) through the box's goal centre so that the goal
    box's outline lies along the goal mask's; `motion` itself where no turn fits it (MIN_ALONG) or the turn is within
    what the outline tells (MIN_TURN_DEG)."""
    centre = motion.apply(box.centre[None])[0]
    goal = motion.apply(box.corners) - centre
    angles = np.radians(np.arange(-SPAN_DEG, SPAN_DEG + 1e-9, STEP_DEG))
    turned = np.einsum("aij,cj->aci", Rotation.from_rotvec(angles[:, None] * up).as_matrix(), goal) + centre
    fits = outline.fits(turned)
    best = int(np.argmin(fits.cost))
    if fits.along[best] < MIN_ALONG:
        return motion
    vertex = parabola_vertex(*fits.cost[best - 1 : best + 2]) if 0 < best < len(angles) - 1 else 0.0
    angle = angles[best] + np.radians(STEP_DEG) * vertex
    if abs(angle) < np.radians(MIN_TURN_DEG):
        return motion
    Y = Rotation.from_rotvec(angle * up).as_matrix()
    return Similarity(motion.scale, Y @ motion.R, Y @ (motion.t - centre) + centre)
