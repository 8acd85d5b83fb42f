"""Whether the views tell the grounded motion from the twins the object's seen shape allows.

A can spun about its axis, a box turned half way, a ball turned any way: the seen shape cannot tell these twins
apart; a print can, and so can a part the first view did not show (a mug's handle behind it that the goal shows).
An editor's goal often breaks the print (its colours drifted, a patch re-textured, the object blurred). So every
twin is checked against both views; the best one is taken, and where another explains the views within TOLD_APART
of it (the margin by which select_motion calls two motions alike) the turn is reported as not seen: the shape's
symmetry goes with the motion, so that planning and verification leave that turn alone instead of trusting a coin
toss.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.compare import half_turn_across
from pipeline.grounding.hypotheses import AXIS_MAPS
from pipeline.grounding.select import HINT_MARGIN
from pipeline.grounding.types import SeenSymmetry
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View, view_consistency

TOLD_APART = HINT_MARGIN
SPIN_STEP_DEG = 45.0  # a body of revolution's twins: spins this far apart


def shape_turns(shape: SeenSymmetry) -> np.ndarray:
    """(K, 3, 3) camera-frame turns about shape.centre that carry the shape onto itself, the identity first."""
    if shape.kind == "box" and shape.rotations is not None:
        others = [g for g in shape.rotations if not np.allclose(g, np.eye(3), atol=1e-6)]
        return np.array([np.eye(3), *others])
    if shape.kind == "ball":
        return np.array([np.eye(3), *(g for g in AXIS_MAPS if not np.allclose(g, np.eye(3)))])
    if shape.axis is None:
        return np.eye(3)[None]
    a = shape.axis / np.linalg.norm(shape.axis)
    spins = Rotation.from_rotvec(np.radians(np.arange(0.0, 360.0, SPIN_STEP_DEG))[:, None] * a).as_matrix()
    if shape.kind != "revolution_ends_alike":
        return spins
    return np.concatenate([spins, spins @ half_turn_across(a)])


def read_turns(
    motion: Similarity,
    shape: SeenSymmetry,
    printed: bool,
    view0: View,
    view1: View,
    K: CameraIntrinsics,
    tol_m: float,
) -> tuple[Similarity, SeenSymmetry, float]:
    """(the twin of `motion` under the shape's turns that best explains the views, the symmetry to report with it,
    the margin by which it beats the next twin): the `shape` symmetry where another twin explains the views within
    TOLD_APART (flagged print_unread when a print shows), none where the views tell it apart."""
    turns = shape_turns(shape)
    twins = [motion.turned_first(g, shape.centre) for g in turns]
    ranked = np.array([view_consistency(t, view0, view1, K, tol_m).ranked for t in twins])
    best = int(np.argmax(ranked))
    if ranked[best] < ranked[0] + TOLD_APART:  # not clearly better than the refined motion itself: keep that
        best = 0
    margin = float(ranked[best] - np.max(np.delete(ranked, best))) if len(ranked) > 1 else float("inf")
    told = margin >= TOLD_APART
    seen = SeenSymmetry("none", shape.centre, shape_kind=shape.kind) if told else replace(shape, print_unread=printed)
    return twins[best], seen, margin
