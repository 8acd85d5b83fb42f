"""Whether a print tells the grounded motion from the twins the object's seen shape allows.

A can spun about its axis, a box turned half way, a ball turned any way: the seen shape cannot tell these twins
apart; a print can. Twins are compared by their print alone (Agreement.pattern: how the colours their points bring
correlate with those they land on, which an editor's gain, offset and blur do not change): the shape is the same
under each turn, and geometry only rewards a twin that keeps the seen side in view. Where no twin's print stands
out from every other's, and from the views compared pixel for pixel as they are (a shadow cast on the object stays
put in the image), the shape's symmetry goes with the motion, flagged print_unread, so that planning and
verification leave that turn alone instead of trusting a coin toss. Only an object whose print shows is read: a
plain one keeps its shape's symmetry.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.compare import half_turn_across, rotation_deg, spins_about
from pipeline.grounding.hypotheses import AXIS_MAPS
from pipeline.grounding.types import SeenSymmetry
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import (
    View,
    brought_colours,
    image_pixels,
    pattern_correlation,
    view_consistency,
    view_evidence,
    view_evidences,
)

TOLD_APART = 0.1  # a twin's print correlates this much better than every other's ...
HALF_AS_WELL = 0.5  # ... and every other's correlates under this share of it: the views tell it apart
SPIN_STEP_DEG = 45.0  # a body of revolution's twins: spins this far apart ...
SPIN_FINE_DEG = 2.0  # ... and the best of them narrowed down to this
MIN_TWIN_GEOMETRY = 0.5  # of the motion's own geometric agreement: a twin must land the object on the goal too


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
    spins = spins_about(a, SPIN_STEP_DEG)
    if shape.kind != "revolution_ends_alike":
        return spins
    return np.concatenate([spins, spins @ half_turn_across(a)])


def read_turns(
    motion: Similarity,
    shape: SeenSymmetry,
    view0: View,
    view1: View,
    K: CameraIntrinsics,
    tol_m: float,
    turns: np.ndarray | None = None,
) -> tuple[Similarity, SeenSymmetry, float]:
    """(the twin of a printed object's `motion` under the shape's turns whose print best follows the views, the
    symmetry to report with it, the margin by which its print beats the next twin's): the `shape` symmetry flagged
    print_unread where no twin's print stands out by TOLD_APART (from the other twins' and from the views left as they
    are, left_in_place), none where one does.

    Twins are ranked by their print alone (Agreement.pattern): the shape is the same under each turn, and what
    geometry adds is which side of the object stays in view: a can truly turned half way carries its seen side out
    of view and lands fewer points on the goal than a twin that keeps it in front, so geometry prefers the wrong
    twin. A body of revolution's best spin is then narrowed down to SPIN_FINE_DEG. `turns` (K, 3, 3), the identity
    first: other twins than the shape's (shape_turns), about shape.centre."""
    turns = shape_turns(shape) if turns is None else turns
    twins = [motion.turned_first(g, shape.centre) for g in turns]
    evidence = view_evidences(twins, view0, view1, K, tol_m)
    # a twin that puts the object elsewhere (the seen centre is off the true axis) is no twin at all
    kept = [k for k, (a, _) in enumerate(evidence) if a.geometry >= MIN_TWIN_GEOMETRY * evidence[0][0].geometry]
    twins, turns = [twins[k] for k in kept], turns[kept]
    pattern = np.array([evidence[k][0].pattern for k in kept])
    landed = [evidence[k][1] for k in kept]
    brought = brought_colours(view0, view1)

    def beats(i: int, j: int) -> float:
        """How far twin j's print falls short of twin i's in following the views, on the points both land on the object:
        by TOLD_APART and to under HALF_AS_WELL of i's correlation, which itself reaches TOLD_APART, or the margin is
        taken as under TOLD_APART. A print no twin follows tells none apart: where the goal shows the side the capture
        did not see (a printed bottle spun half way), every twin kept correlates near or below 0, and one merely less
        negative than the rest beat them by 0.15. A twin is turned about a centre the partial view only estimates, a few
        millimetres off, and a fine print correlates less for that alone (a checkered box whose checker repeats under a
        half turn: 0.87 for the true twin, 0.54 for the half-turned one)."""
        both = np.isfinite(landed[i][:, 0]) & np.isfinite(landed[j][:, 0])
        pi, pj = (pattern_correlation(brought[both], landed[k][both]) for k in (i, j))
        return pi - pj if pi >= TOLD_APART and pj < HALF_AS_WELL * pi else min(pi - pj, 0.0)

    best = int(np.argmax(pattern))
    if best != 0 and beats(best, 0) < TOLD_APART:  # not clearly better than the refined motion itself: keep that
        best = 0
    # twins within a spin step of the best are its neighbours on a continuous spin, not rivals: the finer spin
    # search below settles between them
    rivals = [j for j in range(len(twins)) if rotation_deg(turns[best].T @ turns[j]) > SPIN_STEP_DEG + 1.0]
    # with no rival left (each put the object elsewhere: turned about a centre or axis the capture reads a few
    # millimetres off), the print was never compared and tells nothing: the shape's symmetry goes with the motion
    margin = min((beats(best, j) for j in rivals), default=0.0)
    if margin < TOLD_APART:
        return twins[best], replace(shape, print_unread=True), margin
    chosen, found = twins[best], landed[best]
    if shape.axis is not None:
        chosen = _finer_spin(chosen, shape, float(pattern[best]), view0, view1, K, tol_m)
        found = view_evidence(chosen, view0, view1, K, tol_m)[1]
    # what stays put in the image (a neighbour's shadow, a highlight, the light's fall-off) correlates under any twin
    # that leaves the points where they were: the print tells the twin only where it beats the views compared pixel
    # for pixel, as they are (a faintly printed plate turned in place under a neighbour's shadow was read 123 deg off)
    in_place = left_in_place(view0, view1, K)
    both = np.isfinite(found[:, 0]) & np.isfinite(in_place[:, 0])
    margin = min(
        margin, pattern_correlation(brought[both], found[both]) - pattern_correlation(brought[both], in_place[both])
    )
    if margin < TOLD_APART:
        return twins[best], replace(shape, print_unread=True), margin
    return chosen, SeenSymmetry("none", shape.centre, shape_kind=shape.kind), margin


def left_in_place(view0: View, view1: View, K: CameraIntrinsics) -> np.ndarray:
    """The colour each point of either view finds at its own pixel in the other view, where that shows the object
    (NaN elsewhere; in the order of brought_colours): the views compared as they are, with no motion."""
    found = []
    for src, dst in ((view0, view1), (view1, view0)):
        here = np.full(src.chroma.shape, np.nan)
        u, v, inside = image_pixels(K, src.cloud)
        on = np.zeros(len(src.cloud), dtype=bool)
        on[inside] = dst.mask[v[inside], u[inside]]
        here[on] = dst.chroma_image[v[on], u[on]]
        found.append(here)
    return np.concatenate(found)


def _finer_spin(
    motion: Similarity, shape: SeenSymmetry, pattern: float, view0: View, view1: View, K: CameraIntrinsics, tol_m: float
) -> Similarity:
    """`motion` spun about the shape's axis, in halving steps down to SPIN_FINE_DEG, while its print follows the
    views better."""
    a = shape.axis / np.linalg.norm(shape.axis)
    step = SPIN_STEP_DEG / 2
    while step >= SPIN_FINE_DEG:
        for sign in (1.0, -1.0):
            spun = motion.turned_first(Rotation.from_rotvec(np.radians(sign * step) * a).as_matrix(), shape.centre)
            score = view_consistency(spun, view0, view1, K, tol_m).pattern
            if score > pattern:
                motion, pattern = spun, score
                break
        step /= 2
    return motion
