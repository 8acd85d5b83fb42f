"""The turns of an object that neither its shape nor its print can show, reported with every grounded motion.

A registration of a uniform cube is free to answer any of its 24 quarter-turn twins, a uniform box with a square
cross-section any of 8, a plain can any spin about its axis: the images hold nothing to tell them apart. So the
motion is given with its symmetry, and what consumes it (the benchmark, a planner, a verification) knows which turns
were not measured. The shape comes from the initial points (a ball, a body of revolution and whether its ends look
alike, a box and which of its sides are equal); a print seen on the object in either image (a texture, a decal, a
label: fine detail of brightness or hue standing out of the image's noise) can show every turn; whether the views
then tell the motion from its twins is seen_turns.py's to judge.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from pipeline.contact.symmetry import basis_across, ends_alike, revolution_axis
from pipeline.grounding.compare import SAME_SIDE_M, Symmetry, object_centre, object_symmetry
from pipeline.grounding.hypotheses import AXIS_MAPS, FACE_TOL_DEG, face_frame
from pipeline.grounding.types import SeenSymmetry

BOX_FACE_TOL_REL = 0.03  # a box's seen points lie this close to its faces (share of its size, at least
BOX_FACE_TOL_M = 0.004  # this: a sensor's noise on a small block) ...
BOX_FACE_SHARE = 0.85  # ... this many of them
# a body of revolution whole: the side wall's points (normals off the axis) lie within REVOLUTION_TOL_REL of the
# object's size (at least REVOLUTION_TOL_M) of their slice's radius, REVOLUTION_SHARE of them: a pan's or a mug's
# handle, which the axis fit rightly ignores, breaks it
REVOLUTION_TOL_REL = 0.04
REVOLUTION_TOL_M = 0.003
REVOLUTION_SHARE = 0.97
SLICE_M = 0.005
BALL_NORMAL_DEG = 10.0  # a ball's normals point away from its centre: this close, BALL_NORMAL_SHARE of them
BALL_NORMAL_SHARE = 0.9  # (a bowl's inside lies on a sphere too, its normals pointing in)
BOWL_INWARD_SHARE = 0.6  # points on a sphere, this many facing its centre: a bowl's inside, tried as a revolution
MERIDIAN_SIN = 0.15  # a body of revolution's normals lie off the planes through its axis by this (sine, median)
MERIDIAN_TELLING_SIN = 0.3  # normals this far off the axis (sine) tell where it lies ...
MIN_MERIDIAN_POINTS = 20  # ... this many of them
OUTLINE_BINS = 36  # sectors round a standing axis in which the outline's reach is compared
OUTLINE_REACH_REL = 0.25  # of the typical reach: a handle reaches further (raycast bowls' blobs 0.23, a can 0.23)
OPEN_INWARD_SHARE = 0.1  # a body of revolution with this many points facing its axis is seen into: open at one end
BOX_FACE_FILL = 0.88  # each seen face of MIN_FACE_POINTS fills its rectangle this well (a disc fills pi/4 of it)
MIN_FACE_POINTS = 100
# a face of fewer points (a small box's, a few dozen) that fills its rectangle as well shows a box too, but one that
# does not rules nothing out: a sparse face's hull falls short of its rectangle by its ragged edges (small raycast
# cubes read as none, their faces of 80-96 points filling 0.87-0.89)
SPARSE_FACE_POINTS = 30
EDGE_NORMAL_DEG = 60.0  # a face's points along its edges, their normals bent by the smoothing, lean up to this
SUPPORT_RING_PX = (4, 12)  # the ring around the mask that shows what the object stands on (inner, outer)
SUPPORT_CLEARANCE_M = 0.005
# a part this far from the rest of the seen points (through any chain of them) is not on the object: what the mask
# bled onto in front of or behind it (another bottle, the table far behind its outline): a handle's seen points
# continue from the body's within it
PART_GAP_M = 0.02
# a print: neighbouring pixels PRINT_STEP_PX apart on one smooth patch of surface (normals within
# SAME_NORMAL_DEG, depths within SAME_SURFACE_M) that differ in log brightness or chromaticity beyond
# PRINT_CONTRAST (3.5 times what a sensor's noise of 2-3 levels in 255 leaves on a dark object after PRINT_BLUR_PX),
# on PRINT_SHARE of such pairs: a texture's edges, a decal's rim, a label's band. Shading differs little between
# neighbours whose normals agree, and creases (normals apart) are not compared.
PRINT_STEP_PX = 3
PRINT_BLUR_PX = 1.0
SAME_NORMAL_DEG = 4.0
SAME_SURFACE_M = 0.01
PRINT_CONTRAST = (0.06, 0.03)  # log brightness, chromaticity
PRINT_SHARE = 0.015
PRINT_OUTLINE_PX = 3  # the object's edge against what is behind it is no print
NORMAL_SMOOTH_PX = 2.0
DARK = 30.0  # chromaticity is read where the channels sum to at least this (of 765)


def as_seen(shape: SeenSymmetry, views: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> SeenSymmetry:
    """The shape's symmetry (shape_symmetry), or none when a print shows on the object in any of `views`."""
    if shape.kind != "none" and any(shows_print(*view) for view in views):
        return SeenSymmetry("none", shape.centre, shape_kind=shape.kind)
    return shape


def off_support(
    points: np.ndarray, normals: np.ndarray, point_map: np.ndarray, mask: np.ndarray, up: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The object's points (and normals) more than SUPPORT_CLEARANCE_M above what it stands on, and on its largest
    part (PART_GAP_M): a segmenter's mask bleeds a few pixels onto the table around the object and onto whatever
    stands in front of or behind it, and those points break any shape test (a bottle whose mask reached another in
    front of it read as having a handle). The support's height is the median of the pixels in a ring
    SUPPORT_RING_PX around the mask (point_map: the view's, NaN where unknown; up: the table's normal, camera
    frame). All points where too few are left or the ring shows nothing."""
    near = cv2.dilate(mask.astype(np.uint8), np.ones((2 * SUPPORT_RING_PX[1] + 1,) * 2, np.uint8)).astype(bool)
    inner = cv2.dilate(mask.astype(np.uint8), np.ones((2 * SUPPORT_RING_PX[0] + 1,) * 2, np.uint8)).astype(bool)
    ring = point_map[near & ~inner]
    ring = ring[np.isfinite(ring).all(axis=1)]
    if len(ring) < MIN_FACE_POINTS:
        return points, normals
    keep = points @ up - float(np.median(ring @ up)) > SUPPORT_CLEARANCE_M
    if keep.sum() < MIN_FACE_POINTS:
        return points, normals
    keep[keep] = _largest_part(points[keep])
    return (points[keep], normals[keep]) if keep.sum() >= MIN_FACE_POINTS else (points, normals)


def _largest_part(points: np.ndarray) -> np.ndarray:
    """Which points (N, 3) belong to the largest part whose points each lie within PART_GAP_M of another's."""
    tree = cKDTree(points)
    pairs = tree.query_pairs(PART_GAP_M, output_type="ndarray")
    n = len(points)
    links = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, part = connected_components(links, directed=False)
    return part == np.bincount(part).argmax()


def shape_symmetry(points: np.ndarray, normals: np.ndarray, up: np.ndarray | None = None) -> SeenSymmetry:
    """What the seen points' shape alone cannot show: a ball, a body of revolution, a box's equal sides, or none.
    `up`: the table's normal (camera frame), the axis of a body of revolution standing on it (standing_axis).
    A box's faces are read first: a small box seen on two or three faces also fits slices of a body of revolution
    within their tolerance (raycast boxes read as cans came out 48 and 178 deg off), while no body of revolution
    shows rectangular faces with its points on them."""
    P = np.asarray(points, dtype=np.float64)
    box = box_turns(P, normals)
    if box is not None:  # at least its three half turns about the face axes
        centre, turns = box
        return SeenSymmetry("box", centre, rotations=turns, shape_kind="box")
    revolution = object_symmetry(P)
    if revolution is not None and revolution.axis is None:
        cos = _radial_cosines(P, normals, revolution.centre)
        if np.mean(cos > np.cos(np.radians(BALL_NORMAL_DEG))) >= BALL_NORMAL_SHARE:
            return SeenSymmetry("ball", revolution.centre, shape_kind="ball")
        revolution = None  # a cap of a sphere seen from outside: round only where it stands round the vertical
        if np.mean(cos < 0.0) >= BOWL_INWARD_SHARE:
            axis = revolution_axis(P)  # a bowl's inside: on a sphere, facing in, and it may go round an axis
            revolution = None if axis is None else Symmetry(axis.point, axis.direction, axis.ends_alike)
    standing = False
    if up is not None:  # an axis fitted or none (a can on a few faint slices, a bowl's outside on a sphere)
        fitted, revolution = revolution, on_its_base(P, normals, up, revolution)
        if revolution is None:  # round the vertical but for a handle, or no body of revolution at all
            return SeenSymmetry("none", object_centre(P))
        standing = revolution is not fitted
    if revolution is not None and (standing or _whole_revolution(P, normals, revolution.centre, revolution.axis)):
        open_end = _facing_axis_share(P, normals, revolution.centre, revolution.axis) >= OPEN_INWARD_SHARE
        kind = "revolution_ends_alike" if revolution.ends_alike and not open_end else "revolution"
        return SeenSymmetry(kind, revolution.centre, axis=revolution.axis, shape_kind=kind)
    return SeenSymmetry("none", object_centre(P))


def on_its_base(
    points: np.ndarray, normals: np.ndarray, up: np.ndarray, revolution: Symmetry | None
) -> Symmetry | None:
    """`revolution` (a body of revolution the points (N, 3) were fitted to, None where they fit none) with its axis
    on the vertical `up` where its normals and its outline go round that (standing_axis, _round_outline): whole,
    whatever faces along it, fitted or not; as it is where its normals do not; None where they do but a part reaches
    out on one side (a handle: no body of revolution)."""
    standing = standing_axis(points, normals, up)
    if standing is None:
        return revolution
    if not _round_outline(points, *standing):
        return None
    # whether its ends look alike is read about the vertical: along a fitted axis tilted off it (a can's short seen
    # half) the slices cut it askew and its radius seemed to change
    return Symmetry(standing[0], standing[1], ends_alike(points, *standing))


def standing_axis(points: np.ndarray, normals: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(a point on it, its direction): the table's normal `up` as the axis of the body of revolution the points
    (N, 3) and their normals lie on, through where the normals say, or None when they do not go round it (what
    faces along it, a handle's top, is checked by _round_outline). A body of revolution's normals lie in planes
    through its axis; a shallow dish's points fit many axes (a spherical cap fits any through its centre) and the fit
    from points alone settles on a tilted one (raycast plates 57-89 deg off, bowls 3-28 deg), while one standing on
    its base goes round the vertical."""
    a = up / np.linalg.norm(up)
    centre = vertical_axis_centre(points, normals, a)
    if centre is None:
        return None
    telling = np.linalg.norm(np.cross(normals, a), axis=1) > MERIDIAN_TELLING_SIN
    P, N = points[telling], normals[telling]
    radial = P - centre
    radial -= np.outer(radial @ a, a)
    off = np.linalg.norm(radial, axis=1)
    near = off > 1e-3  # on the axis, the plane through it is any
    if near.sum() < MIN_MERIDIAN_POINTS:
        return None
    sines = np.abs(np.einsum("ij,ij->i", N[near], np.cross(a, radial[near] / off[near, None])))
    return (centre, a) if float(np.median(sines)) <= MERIDIAN_SIN else None


def vertical_axis_centre(points: np.ndarray, normals: np.ndarray, up: np.ndarray) -> np.ndarray | None:
    """Where the vertical axis (along unit `up`) the normals meet passes, at the points' mean height: the point c with
    n . (up x (p - c)) = 0, that is (n x up) . c = (n x up) . p, in least squares over the normals that tell (off the
    axis by MERIDIAN_TELLING_SIN); None with fewer than MIN_MERIDIAN_POINTS of them."""
    across = np.cross(normals, up)
    telling = np.linalg.norm(across, axis=1) > MERIDIAN_TELLING_SIN  # a normal along the axis says nothing of it
    if telling.sum() < MIN_MERIDIAN_POINTS:
        return None
    A = across[telling]
    centre = np.linalg.lstsq(A, np.einsum("ij,ij->i", A, points[telling]), rcond=None)[0]
    return centre + (float(np.mean(points @ up)) - centre @ up) * up


def _round_outline(points: np.ndarray, centre: np.ndarray, axis: np.ndarray) -> bool:
    """Whether the points reach about as far from the axis whichever way round it they lie (the outline seen along
    it, in OUTLINE_BINS sectors, none beyond the typical reach by OUTLINE_REACH_REL of it): a pan's or a mug's
    handle, whose top faces along the axis and tells the normals nothing, reaches out on its side only, by a good
    part of the body's radius; a centre a few millimetres off or a segmenter's blob on the rim do not."""
    outline = _outline(points, centre, axis)
    return outline is not None and outline[1] <= OUTLINE_REACH_REL * outline[0]


def handle_azimuth(points: np.ndarray, centre: np.ndarray, axis: np.ndarray) -> float | None:
    """The angle [rad] about the axis at which a part reaches out beyond the round body (a handle), in the frame
    _azimuths sets up from the axis alone (so two views' angles compare), or None where the outline is round."""
    parts = handle_points(points, centre, axis)
    if parts is None:
        return None
    angle, _ = _azimuths(points[parts[0]], centre, axis)
    return float(np.arctan2(np.sin(angle).sum(), np.cos(angle).sum()))


def handle_points(points: np.ndarray, centre: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(which points (N,) lie well beyond the round body, on the part that reaches out: a handle; which lie within
    the body's typical reach from the axis), or None where the outline seen along the axis is round."""
    outline = _outline(points, centre, axis)
    if outline is None or outline[1] <= OUTLINE_REACH_REL * outline[0]:
        return None
    _, reach = _azimuths(points, centre, axis)
    return reach > outline[0] * (1.0 + 0.5 * OUTLINE_REACH_REL), reach <= outline[0]


def _outline(points: np.ndarray, centre: np.ndarray, axis: np.ndarray) -> tuple[float, float] | None:
    """(the typical reach from the axis over OUTLINE_BINS sectors round it, how far the furthest sector reaches
    beyond that), None where fewer than 3 sectors hold points."""
    angle, reach = _azimuths(points, centre, axis)
    sector = np.floor((angle + np.pi) / (2 * np.pi) * OUTLINE_BINS).astype(int) % OUTLINE_BINS
    outline = [np.percentile(reach[sector == k], 95) for k in range(OUTLINE_BINS) if (sector == k).sum() >= 5]
    if len(outline) < 3:
        return None
    typical = float(np.median(outline))
    return typical, max(outline) - typical


def _azimuths(points: np.ndarray, centre: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(angle [rad] about the axis, distance from it) of each point, the angle from a direction set by the axis."""
    e1, e2 = basis_across(axis)
    off = points - centre
    x, y = off @ e1, off @ e2
    return np.arctan2(y, x), np.hypot(x, y)


def _radial_cosines(points: np.ndarray, normals: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Cosine between each normal and the direction away from `centre`: near 1 on a ball, below 0 in a bowl."""
    radial = points - centre
    radial /= np.maximum(np.linalg.norm(radial, axis=1, keepdims=True), 1e-9)
    return np.einsum("ij,ij->i", radial, normals)


def _facing_axis_share(points: np.ndarray, normals: np.ndarray, point: np.ndarray, axis: np.ndarray) -> float:
    """The share of points whose normal faces the axis (a cup's or a mug's inside): a body seen into is open at one
    end, so it does not look the same turned end for end, whatever its outside's one radius."""
    a = axis / np.linalg.norm(axis)
    off = points - point
    radial = off - np.outer(off @ a, a)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True) + 1e-12
    return float(np.mean(np.einsum("ij,ij->i", normals, radial) < -0.5))


def _whole_revolution(points: np.ndarray, normals: np.ndarray, point: np.ndarray, axis: np.ndarray) -> bool:
    """Whether the side wall's points all lie on the surface of revolution about the axis (see REVOLUTION_SHARE)."""
    side = np.abs(normals @ axis) < 0.7  # a cap's disc faces along the axis
    if side.sum() < 20:
        return False
    off = points[side] - point
    along = off @ axis
    radial = np.linalg.norm(off - np.outer(along, axis), axis=1)
    index = np.floor((along - along.min()) / SLICE_M).astype(int)
    deviation = np.empty(len(radial))
    for k in np.unique(index):
        in_slice = index == k
        deviation[in_slice] = np.abs(radial[in_slice] - np.median(radial[in_slice]))
    tol = max(REVOLUTION_TOL_M, REVOLUTION_TOL_REL * float(np.linalg.norm(np.ptp(points, axis=0))))
    return bool(np.mean(deviation <= tol) >= REVOLUTION_SHARE)


@dataclass(frozen=True)
class SeenBox:
    """The box a view's points lie on (camera frame): its faces' normals (columns of `frame`) and its extent along
    each between `lo` and `hi` (the points' 1st and 99th percentiles, in that frame)."""

    frame: np.ndarray  # (3, 3)
    lo: np.ndarray  # (3,)
    hi: np.ndarray  # (3,)

    @property
    def centre(self) -> np.ndarray:
        return self.frame @ ((self.lo + self.hi) / 2)

    @property
    def corners(self) -> np.ndarray:
        """(8, 3) its corners, camera frame."""
        ends = np.stack([self.lo, self.hi])
        local = np.array([[ends[i, 0], ends[j, 1], ends[k, 2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)])
        return local @ self.frame.T


def seen_box(points: np.ndarray, normals: np.ndarray) -> SeenBox | None:
    """The box the points lie on, or None where they do not: BOX_FACE_SHARE of them on its faces, and the faces seen
    filling their rectangles (_rectangular_faces)."""
    F = face_frame(normals)
    if F is None:
        return None
    local = points @ F
    lo, hi = np.percentile(local, [1, 99], axis=0)
    size = float(np.linalg.norm(hi - lo))
    to_face = np.minimum(np.abs(local - lo), np.abs(local - hi)).min(axis=1)
    tol = max(BOX_FACE_TOL_REL * size, BOX_FACE_TOL_M)
    on_faces = np.mean(to_face <= tol)
    if on_faces < BOX_FACE_SHARE or not _rectangular_faces(local, normals @ F, tol):
        return None
    return SeenBox(F, lo, hi)


def box_turns(points: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """(centre, (K, 3, 3) camera-frame turns about it that map the box onto itself) when the points lie on a box."""
    box = seen_box(points, normals)
    if box is None:
        return None
    F = box.frame
    same = _same_sides(box.hi - box.lo)
    keeps = [P for P in AXIS_MAPS if all(same[j, k] for j, k in enumerate(np.argmax(np.abs(P), axis=1)))]
    # P maps axis j to axis argmax|P[j]|: a turn of the box onto itself when those sides are one length
    return box.centre, np.array([F @ P @ F.T for P in keeps])


def _same_sides(sides: np.ndarray) -> np.ndarray:
    """(3, 3) which sides are one length: within SAME_SIDE_M, and as a partition (sides of 40, 44 and 48 mm
    would make the first two alike and the last two, but not the first and the last; the closer pair is kept),
    so that the turns kept form a group (4, 8 or 24 of them)."""
    gap = np.abs(sides[:, None] - sides[None, :])
    close = [(gap[i, j], i, j) for i, j in ((0, 1), (0, 2), (1, 2)) if gap[i, j] <= SAME_SIDE_M]
    same = np.eye(3, dtype=bool)
    if len(close) == 3:
        return np.ones((3, 3), dtype=bool)
    if close:
        _, i, j = min(close)
        same[i, j] = same[j, i] = True
    return same


def _rectangular_faces(local: np.ndarray, local_normals: np.ndarray, tol_m: float) -> bool:
    """Whether the faces seen fill the smallest rectangle round each in the face's plane (BOX_FACE_FILL): every face
    of MIN_FACE_POINTS, and one at least, a sparse one too (SPARSE_FACE_POINTS); a disc, a pan's bottom, a can's cap
    do not. The smallest, not the one along the frame's other axes: the frame, read from noisy normals, can sit a few
    degrees off a face's edges, and a face twice as long as it is wide then fills under 0.85 of the frame's rectangle
    (raycast boxes read as none). A face is found by its normals (along a frame axis, FACE_TOL_DEG) and then taken
    whole: its points within `tol_m` of its plane whose normals lean less than EDGE_NORMAL_DEG off it. Its normals
    alone leave out its edges, where the smoothing bends them: a face 2-4 cm across came out with its corners round,
    filling 0.75-0.88 of its rectangle, and raycast boxes were read as none (then turned 12-178 deg off)."""
    from scipy.spatial import ConvexHull, QhullError

    seen = 0
    for k in range(3):
        for side in (1.0, -1.0):  # the face the axis points out of, and the one it points into
            along = side * local_normals[:, k]
            core = along > np.cos(np.radians(FACE_TOL_DEG))
            if core.sum() < SPARSE_FACE_POINTS:
                continue
            plane = float(np.median(local[core, k]))
            face = (along > np.cos(np.radians(EDGE_NORMAL_DEG))) & (np.abs(local[:, k] - plane) <= tol_m)
            flat = np.delete(local[face], k, axis=1)
            (_, _), (w, h), _ = cv2.minAreaRect(flat.astype(np.float32))
            area = float(w * h)
            try:
                hull = float(ConvexHull(flat).volume)
            except QhullError:
                return False
            fills = area > 0 and hull >= BOX_FACE_FILL * area
            if not fills and face.sum() >= MIN_FACE_POINTS:
                return False
            seen += fills
    return seen > 0


def shows_print(rgb: np.ndarray, mask: np.ndarray, points: np.ndarray) -> bool:
    """Whether the object (mask) shows a print in the image (see PRINT_CONTRAST), read off pairs of neighbouring
    pixels on one smooth patch of its surface (points: the view's point map)."""
    rows, cols = np.nonzero(mask)
    if len(rows) == 0:
        return False
    margin = int(3 * max(PRINT_BLUR_PX, NORMAL_SMOOTH_PX)) + 1  # the object's box, with room for the smoothing
    box = (
        slice(max(rows.min() - margin, 0), rows.max() + margin + 1),
        slice(max(cols.min() - margin, 0), cols.max() + margin + 1),
    )
    rgb, mask, points = rgb[box], mask[box], points[box]
    inside = cv2.erode(np.asarray(mask, np.uint8), np.ones((2 * PRINT_OUTLINE_PX + 1,) * 2, np.uint8)).astype(bool)
    inside &= np.isfinite(points).all(axis=2)
    if inside.sum() < 50:
        return False
    f = cv2.GaussianBlur(np.asarray(rgb, np.float32), (0, 0), PRINT_BLUR_PX)
    total = f.sum(axis=2)
    log_brightness = np.log(total / 3.0 + 10.0)
    chroma = f[..., :2] / np.maximum(total, DARK)[..., None]
    normals = _normals(points)
    k = PRINT_STEP_PX
    cos_pair, cos_span = np.cos(np.radians(SAME_NORMAL_DEG)), np.cos(np.radians(2 * SAME_NORMAL_DEG))
    same, printed = 0, 0
    for axis in (1, 0):
        # pixel a, its neighbour b = a + k, and the span a - k .. b + k: the smoothed normals blend a crease's two
        # faces near it, but not across the whole span
        b = np.roll(normals, -k, axis=axis)
        span = (np.roll(normals, k, axis=axis) * np.roll(normals, -2 * k, axis=axis)).sum(axis=2)
        pair = inside & np.roll(inside, -k, axis=axis) & ((normals * b).sum(axis=2) > cos_pair)
        pair &= np.nan_to_num(span, nan=-1.0) > cos_span
        pair &= np.abs(points[..., 2] - np.roll(points[..., 2], -k, axis=axis)) < SAME_SURFACE_M
        edge = [slice(None), slice(None)]
        edge[axis] = slice(-2 * k, None)
        pair[tuple(edge)] = False  # rolled round the border
        edge[axis] = slice(None, k)
        pair[tuple(edge)] = False
        step = np.abs(log_brightness - np.roll(log_brightness, -k, axis=axis)) > PRINT_CONTRAST[0]
        step |= np.abs(chroma - np.roll(chroma, -k, axis=axis)).max(axis=2) > PRINT_CONTRAST[1]
        same += int(pair.sum())
        printed += int((pair & step).sum())
    return same >= 50 and printed >= PRINT_SHARE * same


def _normals(points: np.ndarray) -> np.ndarray:
    """Unit normals (H, W, 3) of a point map from its smoothed image-space derivatives (NaN where unknown)."""
    P = np.where(np.isfinite(points), points, 0.0).astype(np.float32)
    w = np.isfinite(points).all(axis=2).astype(np.float32)
    den = cv2.GaussianBlur(w, (0, 0), NORMAL_SMOOTH_PX)[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        P = cv2.GaussianBlur(P * w[..., None], (0, 0), NORMAL_SMOOTH_PX) / den
    du, dv = np.gradient(P, axis=1), np.gradient(P, axis=0)
    n = np.cross(du, dv)
    with np.errstate(invalid="ignore", divide="ignore"):
        return n / np.linalg.norm(n, axis=2, keepdims=True)
