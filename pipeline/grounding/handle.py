"""The turn of a body of revolution with a handle (a mug, a pan) standing on the table, from where its handle points
(and, laid down in the goal, its spin about its own axis).

The body shows no turn about the vertical; only the handle does, and it is too thin for a model's bled goal depth to
place it among the points, so the geometric agreement hardly tells a mug's turns apart. Seen from above, though, the
handle is where the outline reaches out beyond the round body (seen_symmetry.handle_azimuth), in both views: the turn
about the vertical that carries the one direction onto the other, about the body's axis, is offered as a
hypothesis (raycast mugs were 50-175 deg off).

Where the goal's blurred outline reaches out elsewhere too, that hypothesis is off, and the motion chosen keeps the
handle where the capture saw it (the body's seen side kept in view scores best). turn_by_handle then reads the turn
off the goal's silhouette instead: the capture's handle, spun with the body about its axis, must land on the goal's
mask wherever it shows beside the body.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.contact.symmetry import basis_across, revolved
from pipeline.grounding.compare import spins_about, tied_run
from pipeline.grounding.seen_symmetry import handle_azimuth, handle_points, standing_axis, vertical_axis_centre
from pipeline.grounding.seen_turns import read_turns
from pipeline.grounding.tilt import level_twin
from pipeline.grounding.types import SeenSymmetry
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View, depth_tolerance, image_pixels
from pipeline.perception.segmenter import grow

SPIN_STEP_DEG = 5.0  # the turns about the body's axis tried
STANDING_DEG = 10.0  # a motion that tilts the vertical further is spun on its level twin (tilt.level_twin)
MIN_HANDLE_POINTS = 10
BODY_POINTS = 300  # of the body's seen points, swept round its axis to draw its outline in the goal image
OUTLINE_GROW_PX = 3  # the swept points' gaps closed, and a mask's outline a few pixels off
BETTER_BY = 0.2  # of the handle's points: a turn must explain this share more of them than the motion's own
HANDLE_TOLS = 2.0  # a thin handle's goal depth bleeds toward what lies behind it: it is in front only this far
HIDDEN_REACH_REL = 0.4  # a handle reaches this share of the body's radius out of it (raycast mugs' 0.4-1.0)
FACING_COS = 0.5  # the goal's points within 60 deg of the camera's side of the axis
HANDLE_BAND = 0.25  # a handle holds on to the body within the middle half of its height (a mug's: about 0.2-0.8)
TIED = 0.05  # turns within this share of the best explain the goal as well: the handle hides behind the body


def handle_hypotheses(
    seen0: tuple[np.ndarray, np.ndarray], seen1: tuple[np.ndarray, np.ndarray], up: np.ndarray
) -> list[Similarity]:
    """The turn about the vertical `up` (camera frame) that brings the handle of the body standing in the capture
    (`seen0`: its points above the support and their normals) to where the goal's points (`seen1`) show it, the
    body's axis onto the goal's; none unless the capture shows a standing body with a handle and the goal a handle."""
    up = up / np.linalg.norm(up)
    standing = standing_axis(*seen0, up)
    c1 = vertical_axis_centre(*seen1, up)  # the goal's normals are too noisy to test, only to place the axis
    if standing is None or c1 is None:
        return []
    c0, a = standing
    h0, h1 = handle_azimuth(seen0[0], c0, a), handle_azimuth(seen1[0], c1, a)
    if h0 is None or h1 is None:
        return []
    R = Rotation.from_rotvec((h1 - h0) * a).as_matrix()
    return [Similarity(1.0, R, c1 - R @ c0)]


def hidden_handle_turned(
    motion: Similarity, centre: np.ndarray, up: np.ndarray, body: np.ndarray, seen1: np.ndarray
) -> Similarity | None:
    """`motion` spun about the vertical axis (`centre`, unit `up`: camera frame) of a body of revolution standing in
    the capture (`body`: its seen points), which hid its handle behind it, so that the side it hid lands where the
    goal's points (`seen1`: above the support) show a handle; None where they show none. A handle turned toward the
    goal camera reaches out of the body in the goal's depth, not out of its outline
    (handle_outline.hidden_handle_spun): raycast mugs so turned came out 80-180 deg off.
    The goal's points are read about the axis where the motion puts it, against the capture's radius and height, and
    only on the camera's side: a model's depth bleeds the far and side edges back, out of the body's reach, and a
    nearer object's depth in front of the body at that object's own height, not between the body's ends."""
    away = centre - (centre @ up) * up  # from the camera across the axis: the side the capture hid
    c1 = motion.apply(centre[None])[0]
    across = c1 - (c1 @ up) * up  # from the camera across the goal axis, as `away` about the capture's
    if min(np.linalg.norm(away), np.linalg.norm(across)) < 1e-6:  # an axis through the camera: no side is hidden
        return None
    e1, e2 = basis_across(up)
    radius = float(np.percentile(np.hypot((body - centre) @ e1, (body - centre) @ e2), 90))
    heights = (body - centre) @ up
    lo, hi = float(heights.min()), float(heights.max())
    toward = -across / np.linalg.norm(across)  # from the goal axis to the camera's side
    off = seen1 - c1
    azimuth, reach = np.arctan2(off @ e2, off @ e1), np.hypot(off @ e1, off @ e2)
    handle = (reach > (1.0 + HIDDEN_REACH_REL) * radius) & (off @ toward > FACING_COS * reach)
    if handle.sum() < MIN_HANDLE_POINTS:
        return None
    height = float(np.median(off[handle] @ up))
    if not lo + HANDLE_BAND * (hi - lo) <= height <= hi - HANDLE_BAND * (hi - lo):
        return None
    found = np.arctan2(np.sin(azimuth[handle]).sum(), np.cos(azimuth[handle]).sum())
    hidden = motion.R @ away  # where the motion turns the side the capture hid
    turn = found - np.arctan2(hidden @ e2, hidden @ e1)
    return motion.turned_first(Rotation.from_rotvec(turn * up).as_matrix(), centre)


@dataclass(frozen=True)
class HandledBody:
    """A body of revolution with a handle, standing in the capture (camera frame): a point on its axis, the axis (the
    table's normal), the handle's seen points and the body's, and the middle of its seen height on the axis."""

    centre: np.ndarray
    axis: np.ndarray
    handle: np.ndarray
    body: np.ndarray
    middle: np.ndarray

    def whole(self) -> np.ndarray:
        """(N, 3) points on the whole of it: the body's seen slices spun round its axis (revolved), with the handle's
        points."""
        return np.vstack([revolved(self.body, self.centre, self.axis), self.handle])


def handled_body(seen0: tuple[np.ndarray, np.ndarray], up: np.ndarray) -> HandledBody | None:
    """The body with a handle standing in the capture (`seen0`: its points above the support and their normals;
    `up`: the table's normal, camera frame), or None where its normals do not go round the vertical or nothing
    reaches out of its round outline."""
    standing = standing_axis(*seen0, up / np.linalg.norm(up))
    if standing is None:
        return None
    centre, axis = standing
    parts = handle_points(seen0[0], centre, axis)
    if parts is None or parts[0].sum() < MIN_HANDLE_POINTS:
        return None
    heights = seen0[0] @ axis
    middle = centre + (0.5 * float(heights.min() + heights.max()) - float(centre @ axis)) * axis
    return HandledBody(centre, axis, seen0[0][parts[0]], seen0[0][parts[1]], middle)


def turn_by_handle(
    motion: Similarity, handled: HandledBody, view1: View, K: CameraIntrinsics, tol_m: float
) -> Similarity:
    """`motion`, spun about the axis of the body standing in the capture (`handled`), to where its handle best explains
    the goal's silhouette and depth (`view1`); the motion itself unless a turn explains the handle BETTER_BY more
    (_handle_evidence). A motion that leans the body by more than STANDING_DEG (ICP on a
    model's bled goal depth leaned a mug 12-28 deg, and its handle was never read) is spun on its level twin, which
    a turn must beat by as much; tipped further than the twin allows (laid on its side), it is spun as it lies:
    raycast mugs and pans laid down had come out with the handle on the wrong side, 8-135 mm and 20-180 deg off. A
    handle hidden behind the body tells nothing, so where the goal shows none the turns that hide it tie, and the
    middle of them is taken."""
    centre, up = handled.centre, handled.axis  # the axis of a body standing on the table is its normal
    base = motion
    if float(motion.R @ up @ up) < np.cos(np.radians(STANDING_DEG)):  # leaning: its level twin is spun, if it has one
        base = level_twin(motion, up, centre) or motion
    body = handled.body[:: max(1, len(handled.body) // BODY_POINTS)]
    twins = [base.turned_first(g, centre) for g in spins_about(up, SPIN_STEP_DEG)]
    outline = _drawn(np.vstack([t.apply(body) for t in twins]), K)  # the same whichever way the body is spun
    outline = grow(outline, OUTLINE_GROW_PX)
    tol_m = depth_tolerance(tol_m, view1)
    scores = np.array([_handle_evidence(t.apply(handled.handle), outline, view1, K, tol_m) for t in twins])
    best = _middle_of_best(scores)
    return twins[best] if scores[best] >= scores[0] + BETTER_BY else motion


def ends_by_print(
    motion: Similarity, handled: HandledBody, view0: View, view1: View, K: CameraIntrinsics, tol_m: float
) -> Similarity:
    """`motion`, or its twin turned end for end by a half turn about the handle's line through the middle of the
    body's height, where the body's print tells that twin apart (seen_turns.read_turns). The half turn keeps a handle
    half way up where it was and swaps the open end for the closed one, which a model's goal depth hardly shows: a
    raycast mug laid on its side, its handle read right (turn_by_handle), came out 180 deg off with the print
    correlating -0.57 against the twin's 0.51."""
    off = handled.handle - handled.centre
    out = (off - np.outer(off @ handled.axis, handled.axis)).mean(axis=0)  # from the axis to the handle
    if np.linalg.norm(out) < 1e-6:
        return motion
    half = Rotation.from_rotvec(np.pi * out / np.linalg.norm(out)).as_matrix()
    twins = np.array([np.eye(3), half])
    twin, read, _ = read_turns(motion, SeenSymmetry("none", handled.middle), view0, view1, K, tol_m, twins)
    return twin if not read.print_unread else motion


def _handle_evidence(X: np.ndarray, outline: np.ndarray, view1: View, K: CameraIntrinsics, tol_m: float) -> float:
    """(explained - contradicted) / all, of the handle points X (N, 3): beside the body's outline in the goal image,
    on the goal's mask or off it; over the body, at the goal's depth or well in front of it (a handle turned
    toward the camera where the goal shows the body behind). Behind the body they tell nothing."""
    count, X = len(X), X[X[:, 2] > 1e-3]
    u, v, inside = image_pixels(K, X)
    u, v, z = u[inside], v[inside], X[inside, 2]
    beside, on_mask, d = ~outline[v, u], view1.mask[v, u], view1.depth[v, u]
    with np.errstate(invalid="ignore"):  # NaN depth: no evidence
        at_depth, in_front = np.abs(z - d) <= tol_m, z < d - HANDLE_TOLS * tol_m
    explained = np.where(beside, on_mask, on_mask & at_depth)
    contradicted = np.where(beside, ~on_mask, in_front)
    return float(explained.sum() - contradicted.sum()) / count


def _drawn(X: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """(H, W) the pixels points X (N, 3) project onto."""
    image = np.zeros((K.height, K.width), dtype=bool)
    u, v, inside = image_pixels(K, X[X[:, 2] > 1e-3])
    image[v[inside], u[inside]] = True
    return image


def _middle_of_best(scores: np.ndarray) -> int:
    """The index in the middle of the run (round the circle of turns) of scores within TIED of the best."""
    top = int(np.argmax(scores))
    tied = scores >= scores[top] - TIED
    if tied.all():
        return top
    lo, hi = tied_run(tied, top)
    return ((lo + hi) // 2) % len(scores)
