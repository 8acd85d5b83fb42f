"""An object moved about a table is seldom left leaning: a motion that tilts the vertical a little, and explains the
views no better than the same motion without the tilt, is taken without it. Nor is it often turned over: a motion
that turns its top down must explain the views clearly better than one that keeps it up (ranks_above).

A small object's faces in a model's noisy goal depth fit a tilt of 20-30 deg about as well as none (a 6 cm box turned
on the table came out tilted 25 deg, its view agreement 0.84 against the truth's 0.83), and ICP, polishing on that
depth, drifts into such tilts. The level twin is the motion followed by the least turn, about where the motion puts
the object's centre, that brings the vertical back onto itself; a real tilt shows as a better view agreement.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.umeyama import Similarity

LEVEL_DEG = 30.0  # tilts up to this are tried without (a tip stands an object on another face, 90 deg)
# the tilted motion must explain this much more of the views (geometric agreement) to keep its tilt: a model's warped
# goal depth favours a false tilt of 2-10 deg by up to 0.05 (raycast goals left level), a real one of 9-35 deg
# shows by 0.09 or more (MuJoCo boxes tipped 9.5 and 10.7 deg: 0.09, 0.12; raycast tips 0.10-0.49)
NO_BETTER = 0.07
# a motion that turns the object's top down (the vertical turned more than LYING_DEG past laid on its side) must rank
# this much above one that keeps it up (select.Selected.ranked): a model's goal depth fills a hollow from its rim, and
# a mug seen into, or a pan, turned upside down hides the inside it cannot explain (raycast mugs slid on the table came
# out upside down, 175-179 deg off, outranking their upright twins by 0.05-0.07)
TURNED_OVER_MARGIN = 0.1
LYING_DEG = 20.0  # tilts this close to 90 deg lay the object on its side: which end leads says nothing of up or down


def tilt_deg(R: np.ndarray, up: np.ndarray) -> float:
    """How far the rotation `R` tilts the vertical `up` (unit, same frame) [deg]."""
    return float(np.degrees(np.arccos(np.clip((R @ up) @ up, -1.0, 1.0))))


def level_twin(motion: Similarity, up: np.ndarray, centre: np.ndarray) -> Similarity | None:
    """`motion` without its tilt of the vertical `up` (camera frame), turned about where it puts `centre`; None where
    it tilts by more than LEVEL_DEG or by nothing."""
    up = up / np.linalg.norm(up)
    tilted = motion.R @ up
    axis = np.cross(tilted, up)
    angle = float(np.arctan2(np.linalg.norm(axis), tilted @ up))
    if angle > np.radians(LEVEL_DEG) or angle < 1e-6:
        return None
    G = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()
    p = motion.apply(centre[None])[0]
    return motion.turned_after(G, p)


def kept_level(
    motion: Similarity, up: np.ndarray, centre: np.ndarray, geometry: Callable[[Similarity], float]
) -> Similarity:
    """`motion`'s level twin where its `geometry` (the views' geometric agreement with a motion) is no more than
    NO_BETTER below the motion's own; the motion where its tilt shows or is out of LEVEL_DEG."""
    level = level_twin(motion, up, centre)
    if level is None or geometry(level) < geometry(motion) - NO_BETTER:
        return motion
    return level


def ranks_above(ranked_a: float, R_a: np.ndarray, ranked_b: float, R_b: np.ndarray, up: np.ndarray) -> bool:
    """Whether a motion (its rotation R_a, what it ranks on: select.Selected.ranked) ranks above another, by
    TURNED_OVER_MARGIN less where it keeps the object's top up and the other turns it over, more the other way round."""

    def side(R: np.ndarray) -> int:  # 1: top up, -1: turned over, 0: laid on its side
        tilt = tilt_deg(R, up)
        return 1 if tilt < 90.0 - LYING_DEG else (-1 if tilt > 90.0 + LYING_DEG else 0)

    a, b = side(R_a), side(R_b)
    bonus = TURNED_OVER_MARGIN if a > 0 > b else (-TURNED_OVER_MARGIN if b > 0 > a else 0.0)
    return ranked_a + bonus > ranked_b
