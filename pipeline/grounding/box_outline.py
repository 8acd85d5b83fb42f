"""A box's turn about the vertical, read from the goal mask's outline.

A model's goal depth tilts a small box's faces by 5-10 deg (its edges bled into what lies behind them, the noise
smoothed over that bleed, a slow warp left under it), and the registration follows: boxes standing on the table came
out turned 6-25 deg about the vertical from where the goal image shows them (raycast pairs). The outline does not
depend on that depth. A box's outline is the convex hull of its eight corners' images: the capture's measured points
give the box (seen_symmetry.seen_box), the motion carries it to the goal, and of its turns about the vertical through
its goal centre the one is taken whose hull lies along the goal mask's outline best (outline_fit.py). Where the
depth also leaned a box standing on the table (by 10-24 deg: no turn about the vertical then fits), its turns are
tried set down on the face nearest the table too (face_down), and the best of either kept.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.compare import turns_onto
from pipeline.grounding.outline_fit import GoalOutline, refined_angle, turned_about
from pipeline.grounding.seen_symmetry import SeenBox
from pipeline.grounding.umeyama import Similarity

SPAN_DEG, STEP_DEG = 30.0, 1.0  # turns tried either way about the vertical, and their step
MIN_ALONG = 0.7  # the hull's share along the outline at its best turn: less, and the outline is not this box's
# a hull drawn from seen points and a ragged outline tell a turn to a degree or two: a smaller one is left to the
# depth (MuJoCo boxes, their goal depth good to 0.2 %, came out 0.1 -> 1.3 deg off)
MIN_TURN_DEG = 2.0
# a box rests on a face: a model's goal depth had leaned standing boxes by 10-24 deg (their outline no turn about the
# vertical fitted), while a box leaning further may stand on an edge as the goal shows it. A small lean is set on
# its face too, where that fits better: leaving leans under 5 deg to the depth lost as much as it gained on the
# raycast boxes (57 right against 58 of 79); on MuJoCo's goal depth, good to 0.2 %, boxes so set came out up to
# 1 deg off, the box's faces being read from its seen normals to about that
FACE_DOWN_DEG = 25.0


def turned_to_outline(motion: Similarity, box: SeenBox, up: np.ndarray, outline: GoalOutline) -> Similarity:
    """`motion` turned about the vertical `up` (unit, camera frame) through the box's goal centre so that the goal
    box's outline lies along the goal mask's, tried as it is and set down on the face nearest the table
    (face_down); `motion` itself where no turn fits it (MIN_ALONG) or the turn is within what the outline tells
    (MIN_TURN_DEG)."""
    centre = motion.apply(box.centre[None])[0]
    starts = [motion] + [flat for flat in (face_down(motion, box, up),) if flat is not None]
    angles = np.radians(np.arange(-SPAN_DEG, SPAN_DEG + 1e-9, STEP_DEG))
    fits = outline.fits(
        np.concatenate([turned_about(start.apply(box.corners), centre, up, angles) for start in starts])
    )
    cost = fits.cost.reshape(len(starts), len(angles))
    which, best = np.unravel_index(int(np.argmin(cost)), cost.shape)
    if fits.along.reshape(cost.shape)[which, best] < MIN_ALONG:
        return motion
    angle = refined_angle(cost[which], angles, int(best))
    start = starts[which]
    if abs(angle) < np.radians(MIN_TURN_DEG):
        return start
    Y = Rotation.from_rotvec(angle * up).as_matrix()
    return start.turned_after(Y, centre)


def face_down(motion: Similarity, box: SeenBox, up: np.ndarray) -> Similarity | None:
    """`motion` turned about the box's goal centre so that the goal box's face nearest the table lies on it (its
    normal along the vertical `up`, unit), where that face leans by under FACE_DOWN_DEG; None where it leans more
    or not at all."""
    normal, lean = _lowest_face(motion, box, up)
    if not 1e-6 < lean < FACE_DOWN_DEG:
        return None
    G = turns_onto(normal, up[None])[0]
    centre = motion.apply(box.centre[None])[0]
    return motion.turned_after(G, centre)


def face_lean_deg(motion: Similarity, box: SeenBox, up: np.ndarray) -> float:
    """How far [deg] the goal box's face nearest the table leans off it."""
    return _lowest_face(motion, box, up)[1]


def _lowest_face(motion: Similarity, box: SeenBox, up: np.ndarray) -> tuple[np.ndarray, float]:
    """(the outward normal of the goal box's face nearest the table, turned to face down the vertical `up`; how far
    [deg] it leans off it)."""
    faces = motion.R @ box.frame
    along = faces.T @ up
    k = int(np.argmax(np.abs(along)))
    normal = faces[:, k] * np.sign(along[k])
    return normal, float(np.degrees(np.arccos(np.clip(normal @ up, -1.0, 1.0))))
