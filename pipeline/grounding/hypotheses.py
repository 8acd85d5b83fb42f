"""Motion hypotheses from the object clouds' geometry alone, to complement the feature consensus.

On uniform or symmetric objects feature matches are ambiguous and RANSAC may never sample the right motion.
Objects on a table mostly turn about the table normal and sometimes tip over, so a sweep of rotations
yaw(a) . tilt(theta) . yaw(b) about the normal, each with the translation that aligns the cloud centroids,
covers the likely motions at a coarse step. A vectorised render-and-compare check (soft silhouette and depth
agreement at a coarse tolerance, both ways, colour only weighting it as verify's tie-break does) keeps the few worth
refining, their shifts slid onto the goal's surface. Colour as a factor buried the truth's neighbours: a step off
the truth, with the centroids of a model's distorted goal cloud centimetres off, lands a print's colours elsewhere
(a printed bowl turned in place: no level turn scored over 0.15, tilted ones 0.36, and the best eight hypotheses
tilted it 30-60 deg; the level turns found, which turn of the print is right is read afterwards, seen_turns.py).

A ball shows no turn, and where it went is the centre of the sphere its seen points lie on: the centres fitted
in both views give its shift however little of it the goal shows (a ball put into a bowl shows its top over the
wall, whose centroid is not that of the front the capture saw).

A sweep step is too coarse for boxes: after a tilt, a near-cubic box turned 20-30 deg from the truth looks
more like a wrong face than the right one. Box-like objects show two or three planar faces, so the frames of
their two dominant perpendicular faces in the two views give the rotation up to how the axes map (24 cases)
to within a degree or two, however far the object turned; a point-to-plane slide finds the shift.

A body of revolution's turn is where its axis goes: its axis is tried in every direction (axis_hypotheses), not only
at the sweep's tilts, each spun so that the side the capture saw faces the goal camera.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.contact.symmetry import ball_centre, basis_across
from pipeline.grounding.compare import half_turn_across, sphere_directions, spins_about, turns_onto
from pipeline.grounding.types import SeenSymmetry
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import COLOUR_WEIGHT, View, depth_tolerance

MAX_POINTS = 120  # per cloud: a coarse check needs the shape, not every point
CHROMA_SIGMA = 0.08
SILHOUETTE_SIGMA_REL = 0.1  # soft-silhouette width / object size
DEPTH_TOL_REL = 0.15  # depth agreement width / object size
DISTINCT_PEAKS = 10  # sweep rotations at least SEED_SEPARATION_DEG apart, ranked first
SEED_SEPARATION_DEG = 20.0
FACE_TOL_DEG = 12.0  # normals within this angle belong to one planar face
MIN_FACE_POINTS = 5
RECTANGLE_FILL = 0.9  # a box's footprint seen from above fills its smallest rectangle this well
FACE_POINTS = 400  # normals looked at to find the faces
SHIFT_ITERATIONS = 5
BALL_FIT_REL = 0.05  # the goal's points lie on the capture's ball: median distance off it / its radius


def _signed_permutations() -> np.ndarray:
    """(24, 3, 3) the proper rotations that map coordinate axes onto coordinate axes."""
    out = []
    for perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1), (0, 2, 1), (2, 1, 0), (1, 0, 2)):
        for signs in np.ndindex(2, 2, 2):
            P = np.zeros((3, 3))
            P[np.arange(3), perm] = np.where(np.array(signs) == 1, -1.0, 1.0)
            if np.linalg.det(P) > 0:
                out.append(P)
    return np.array(out)


AXIS_MAPS = _signed_permutations()


def rotation_sweep(
    up: np.ndarray, yaw_step_deg: float = 15.0, tilts_deg: tuple[float, ...] = (30.0, 60.0, 90.0)
) -> np.ndarray:
    """(M, 3, 3) rotations about `up` combined with tilts about an axis perpendicular to it."""
    up = up / np.linalg.norm(up)
    side = np.cross(up, [1.0, 0.0, 0.0])
    if np.linalg.norm(side) < 0.1:
        side = np.cross(up, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side)
    yaws = np.radians(np.arange(0.0, 360.0, yaw_step_deg))
    Ra = Rotation.from_rotvec(yaws[:, None] * up)
    out = [Ra.as_matrix()]
    coarse = Rotation.from_rotvec(np.radians(np.arange(0.0, 360.0, 2 * yaw_step_deg))[:, None] * up)
    for tilt in tilts_deg:
        Rt = Rotation.from_rotvec(np.radians(tilt) * side)
        for b in coarse:
            out.append((Ra * Rt * b).as_matrix())
    return np.concatenate(out)


def _agreement(
    X: np.ndarray,
    normals: np.ndarray,
    chroma: np.ndarray,
    other: View,
    closeness: np.ndarray,
    K: CameraIntrinsics,
    tol_m: float,
) -> np.ndarray:
    """(M, N, 3) moved points -> mean soft agreement (silhouette x depth, colour weighted in by COLOUR_WEIGHT) of the
    camera-facing, not occluded ones with the other view."""
    facing = np.einsum("mnk,mnk->mn", normals, X) < 0  # einsum: a length-3 axis's sum() is the sweep's slowest step
    z = np.maximum(X[..., 2], 1e-3)
    u = np.round(K.fx * X[..., 0] / z + K.cx).astype(int)
    v = np.round(K.fy * X[..., 1] / z + K.cy).astype(int)
    inside = (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    pixel = np.where(inside, v * K.width + u, 0)  # looked up by flat index: np.take, 4x faster than image[v, u]
    d = np.take(other.depth, pixel)
    seen = np.isfinite(d)
    d = np.where(seen, d, z)
    counted = facing & (~inside | ~seen | (z < d + tol_m))  # points behind the observed surface: no evidence
    off = np.take(other.chroma_image.reshape(-1, 3), pixel, axis=0) - chroma[None]
    colour = np.exp(-np.einsum("mnk,mnk->mn", off, off) / CHROMA_SIGMA**2)
    geometry = inside * np.take(closeness, pixel) * np.exp(-(((z - d) / tol_m) ** 2))
    hit = geometry * (1.0 - COLOUR_WEIGHT + COLOUR_WEIGHT * colour)
    return (hit * counted).sum(axis=1) / np.maximum(counted.sum(axis=1), 1)


def mask_closeness(mask: np.ndarray, sigma_px: float) -> np.ndarray:
    """1 on the mask, falling off as a Gaussian of the distance to it [px]: a soft silhouette."""
    import cv2

    d = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)
    return np.exp(-((d / max(sigma_px, 0.5)) ** 2))


def coarse_scores(
    rotations: np.ndarray,
    view0: View,
    view1: View,
    closeness0: np.ndarray,
    closeness1: np.ndarray,
    K: CameraIntrinsics,
    tol_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Score each rotation, with the translation that aligns the cloud centroids, initial -> goal and back.
    Returns scores (M,) in 0..1 and translations (M, 3)."""
    s0, s1 = coarse_step(len(view0.cloud)), coarse_step(len(view1.cloud))
    p0, n0, k0 = view0.cloud[::s0], view0.normals[::s0], view0.chroma[::s0]
    p1, n1, k1 = view1.cloud[::s1], view1.normals[::s1], view1.chroma[::s1]
    p0, n0, p1, n1 = (a.astype(np.float32) for a in (p0, n0, p1, n1))  # float32 halves the memory traffic
    rotations = rotations.astype(np.float32)
    Rt = rotations.transpose(0, 2, 1)  # batched matmul (BLAS) rather than einsum: the sweep's hot spot
    c0, c1 = view0.cloud.mean(axis=0), view1.cloud.mean(axis=0)
    t = (c1 - c0 @ Rt).astype(np.float32)
    X = p0 @ Rt + t[:, None]
    fwd = _agreement(X, n0 @ Rt, k0, view1, closeness1, K, tol_m)
    Y = (p1[None] - t[:, None]) @ rotations
    bwd = _agreement(Y, n1 @ rotations, k1, view0, closeness0, K, tol_m)
    return (0.5 * (fwd + bwd)).astype(np.float64), t.astype(np.float64)


def face_frame(normals: np.ndarray) -> np.ndarray | None:
    """(3, 3) frame (columns) of the two most populated, mutually perpendicular planar faces in a view, or None
    when fewer than two such faces are seen. For a box these are two of its face normals, whatever the view."""
    cos_tol, sin_tol = np.cos(np.radians(FACE_TOL_DEG)), np.sin(np.radians(FACE_TOL_DEG))

    def dominant(n: np.ndarray) -> np.ndarray:
        close = (n @ n.T) > cos_tol
        d = n[close[np.argmax(close.sum(axis=1))]].mean(axis=0)
        return d / np.linalg.norm(d)

    normals = normals[:: max(1, len(normals) // FACE_POINTS)]
    a = dominant(normals)
    perpendicular = normals[np.abs(normals @ a) < sin_tol]
    if len(perpendicular) < MIN_FACE_POINTS:
        return None
    b = dominant(perpendicular)
    b -= (b @ a) * a
    b /= np.linalg.norm(b)
    return np.stack([a, b, np.cross(a, b)], axis=1)


def coarse_step(points: int) -> int:
    """Every how many of a cloud's `points` a coarse check takes: MAX_POINTS to twice as many (all of a smaller one)."""
    return max(1, points // MAX_POINTS)


def face_hypotheses(view0: View, view1: View) -> list[Similarity]:
    """Motions that carry the initial view's face frame onto the goal view's, for each way the axes can map
    (24): exact, up to sensor noise, for box-like objects, however far they turned; centroids aligned."""
    F0, F1 = face_frame(view0.normals), face_frame(view1.normals)
    if F0 is None or F1 is None:
        return []
    rotations = F1 @ AXIS_MAPS @ F0.T
    p0 = view0.cloud[:: coarse_step(len(view0.cloud))]
    t = view1.cloud.mean(axis=0) - (p0 @ rotations.transpose(0, 2, 1)).mean(axis=1)
    return [Similarity(1.0, R, tt) for R, tt in zip(rotations, slid(rotations, t, view0, view1), strict=True)]


def slid(rotations: np.ndarray, t: np.ndarray, view0: View, view1: View) -> np.ndarray:
    """(M, 3) the shifts t (M, 3) slid, the rotations kept, until the capture's points lie on the goal's surface
    (point-to-plane, the nearest 70 % of pairs). Two views see different parts of an object, and a tip or a turn
    shows the goal camera parts the capture never saw: their centroids can lie centimetres apart (tipped pans and
    plates turned within 13 deg of the truth were put 4-10 cm off it, too far for ICP to pull in)."""
    from scipy.spatial import cKDTree

    tree = cKDTree(view1.cloud)
    p0 = view0.cloud[:: coarse_step(len(view0.cloud))]
    moved = p0 @ rotations.transpose(0, 2, 1)  # (M, N, 3)
    m, k = moved.shape[:2]
    for _ in range(SHIFT_ITERATIONS):  # partial views: the centroids differ; slide onto the goal's faces
        X = moved + t[:, None]
        dist, j = tree.query(X.reshape(-1, 3))
        dist, j = dist.reshape(m, k), j.reshape(m, k)
        w = (dist <= np.percentile(dist, 70, axis=1, keepdims=True)).astype(float)[..., None]
        n = view1.normals[j] * w  # (M, N, 3), far pairs weighted out
        r = np.einsum("mki,mki->mk", n, view1.cloud[j] - X)
        A = np.einsum("mki,mkj->mij", n, n) + 1e-3 * k * np.eye(3)
        t = t + np.linalg.solve(A, np.einsum("mki,mk->mi", n, r)[..., None])[..., 0]  # point-to-plane, shift only
    return t


def footprint_hypotheses(points0: np.ndarray, points1: np.ndarray, up: np.ndarray) -> list[Similarity]:
    """Turns about the vertical that carry the smallest rectangle round the capture's footprint (its points above the
    support, seen from above) onto the goal's, one for each way its sides can map (4), its middle onto the goal's
    at the same height as its points stood: a box slid or turned on the table, whose faces a small, noisy goal view
    shows too few normals of for face_hypotheses (raycast boxes turned 16-60 deg off the truth, their footprints'
    within 5 deg). None where either footprint does not fill its rectangle (a disc fills pi/4 of it)."""
    if len(points0) < MIN_FACE_POINTS or len(points1) < MIN_FACE_POINTS:
        return []
    import cv2

    up = up / np.linalg.norm(up)
    e1, e2 = basis_across(up)

    def footprint(P: np.ndarray) -> tuple[float, np.ndarray, bool]:
        flat = np.column_stack([P @ e1, P @ e2]).astype(np.float32)
        (x, y), (w, h), angle = cv2.minAreaRect(flat)
        boxy = cv2.contourArea(cv2.convexHull(flat)) >= RECTANGLE_FILL * w * h
        return np.radians(angle), x * e1 + y * e2 + float(np.mean(P @ up)) * up, boxy

    (a0, c0, boxy0), (a1, c1, boxy1) = footprint(points0), footprint(points1)
    if not (boxy0 and boxy1):  # a round footprint's rectangle turns with nothing
        return []
    out = []
    for k in range(4):
        R = Rotation.from_rotvec((a1 - a0 + k * np.pi / 2) * up).as_matrix()
        out.append(Similarity(1.0, R, c1 - R @ c0))
    return out


def ball_hypotheses(view0: View, view1: View) -> list[Similarity]:
    """The shift (no turn) from the centre of the ball the capture's cloud lies on to the centre of a ball of the
    same radius fitted to the goal's cloud, however little of it that shows (a cap over a bowl's wall is too
    small a part of a sphere to tell a ball by itself); none when either is no ball."""
    c0 = ball_centre(view0.cloud)
    if c0 is None:
        return []
    radius = float(np.median(np.linalg.norm(view0.cloud - c0, axis=1)))
    seen = view1.cloud.mean(axis=0)
    start = seen + radius * seen / np.linalg.norm(seen)  # behind the seen surface, away from the camera
    fit = least_squares(lambda c: np.linalg.norm(view1.cloud - c, axis=1) - radius, start, loss="soft_l1")
    off = np.abs(np.linalg.norm(view1.cloud - fit.x, axis=1) - radius)
    if float(np.median(off)) > BALL_FIT_REL * radius:
        return []
    return [Similarity(1.0, np.eye(3), fit.x - c0)]


def sweep_hypotheses(
    view0: View, view1: View, K: CameraIntrinsics, up: np.ndarray, keep: int, size_m: float
) -> list[Similarity]:
    """The `keep` best rotations of the sweep (_best_rotations)."""
    return _best_rotations(rotation_sweep(up), view0, view1, K, size_m, (DISTINCT_PEAKS, SEED_SEPARATION_DEG), keep)


def _best_rotations(
    rotations: np.ndarray,
    view0: View,
    view1: View,
    K: CameraIntrinsics,
    size_m: float,
    distinct: tuple[int, float],
    keep: int,
) -> list[Similarity]:
    """The `keep` rotations (M, 3, 3) that score best on the coarse check, the best `distinct[0]` mutually distinct
    ones (`distinct[1]` deg apart) first: neighbours of one peak would otherwise crowd out the other candidates. The
    tolerances scale with the object (the centroids of two partial views can differ by a good part of its size), and
    the kept ones' shifts are slid off the centroids' onto the goal's surface (slid)."""
    sigma_px = SILHOUETTE_SIGMA_REL * size_m * K.fx / float(np.median(view0.cloud[:, 2]))
    closeness0 = mask_closeness(view0.mask, sigma_px)
    closeness1 = mask_closeness(view1.mask, sigma_px)
    tol = depth_tolerance(DEPTH_TOL_REL * size_m, view0, view1)
    scores, t = coarse_scores(rotations, view0, view1, closeness0, closeness1, K, tol)
    order = np.argsort(-scores)
    peaks = list(order[_distinct(rotations[order], distinct[1], distinct[0])])
    ranked = (peaks + [k for k in order[:keep] if k not in set(peaks)])[:keep]
    if not ranked:
        return []
    shifts = slid(rotations[ranked], t[ranked], view0, view1)
    return [Similarity(1.0, rotations[k], shift) for k, shift in zip(ranked, shifts, strict=True)]


def _distinct(rotations: np.ndarray, min_deg: float, count: int) -> list[int]:
    """Indices of up to `count` rotations, in order, each at least min_deg from those already taken."""
    taken: list[int] = []
    cos_min = np.cos(np.radians(min_deg))
    for i, R in enumerate(rotations):
        if all((np.trace(rotations[j].T @ R) - 1) / 2 < cos_min for j in taken):
            taken.append(i)
            if len(taken) == count:
                break
    return taken


END_FOR_END_SPIN_DEG = 30.0  # a body of revolution's twins spun about its axis in these steps (end_for_end, spun)


def end_for_end(motion: Similarity, shape: SeenSymmetry, points0: np.ndarray, points1: np.ndarray) -> list[Similarity]:
    """The motion's twins turned end for end first (a half turn across a body of revolution's axis, about the
    middle of its seen length; points0 its seen points), then spun about its axis in END_FOR_END_SPIN_DEG steps (the
    spin decides which side of the seen surface faces the camera), each also slid along the axis until the middles of
    the two views' lengths meet (points1: the goal's): a bottle's registration may settle on the twin that puts its neck
    where its base goes, which no hypothesis near the truth then corrects. None for any other shape."""
    if shape.axis is None:
        return []
    a = shape.axis / np.linalg.norm(shape.axis)
    middle = shape.centre + a * _mid((points0 - shape.centre) @ a)
    a1 = motion.R @ a  # the axis where the goal has it
    spins = spins_about(a, END_FOR_END_SPIN_DEG)
    out = []
    for H in spins @ half_turn_across(a):
        twin = motion.turned_first(H, middle)
        slide = _mid(points1 @ a1) - _mid(twin.apply(points0) @ a1)
        out += [twin, Similarity(twin.scale, twin.R, twin.t + slide * a1)]
    return out


def spun(motion: Similarity, shape: SeenSymmetry) -> list[Similarity]:
    """The motion's twins spun about a body of revolution's axis in END_FOR_END_SPIN_DEG steps (itself left out): the
    spin decides which side of the partial seen surface faces the goal camera, and ICP from one spin settles where it
    starts (a tipped bottle's winner at view agreement 0.29, its twin spun 30 deg back 0.39): ground() tries them on a
    winner the views do not bear out before refusing it. None for any other shape."""
    if shape.axis is None:
        return []
    a = shape.axis / np.linalg.norm(shape.axis)
    return [motion.turned_first(S, shape.centre) for S in spins_about(a, END_FOR_END_SPIN_DEG)[1:]]


def _mid(values: np.ndarray) -> float:
    """The middle of the values' extent, robust to a few strays."""
    return 0.5 * float(np.percentile(values, 1) + np.percentile(values, 99))


AXIS_DIRECTIONS = 600  # a body of revolution's goal axis tried in this many directions, any axis within 7 deg of one
AXIS_PEAKS = 4  # the best mutually distinct ones kept ...
AXIS_SEPARATION_DEG = 15.0  # ... this far apart (the sweep's peaks: 20 deg, on a grid of 15 to 30)


def axis_hypotheses(
    view0: View, view1: View, K: CameraIntrinsics, shape: SeenSymmetry, size_m: float
) -> list[Similarity]:
    """A body of revolution's motion is where its axis goes (its spin about it shows nothing but a print, which
    seen_turns.py reads afterwards): its axis is tried in AXIS_DIRECTIONS directions spread over the sphere, each
    spun so that the side the capture saw faces the goal camera (a partial cloud turned away explains nothing), and
    scored like the sweep. The sweep's tilts are 30 deg apart and stop at 90: raycast cylinders whose goal axis lay
    20-30 deg from every rotation it tries came out 5-20 deg off; one of these put the axis within 10 deg, and ICP
    took it the rest of the way (a cylinder turned 69 deg: 19.7 -> 0.0 deg, 12.2 -> 1.2 mm). None for any other
    shape."""
    if shape.axis is None:
        return []
    a0 = shape.axis / np.linalg.norm(shape.axis)
    d = sphere_directions(AXIS_DIRECTIONS)
    onto = turns_onto(a0, d)
    seen = _across(onto @ _across(view0.cloud.mean(axis=0) - shape.centre, a0), d)  # the seen side, off the axis
    want = _across(np.broadcast_to(-view1.cloud.mean(axis=0), d.shape), d)  # toward the goal camera
    angle = np.arctan2(np.einsum("ij,ij->i", np.cross(seen, want), d), np.einsum("ij,ij->i", seen, want))
    rotations = Rotation.from_rotvec(angle[:, None] * d).as_matrix() @ onto
    return _best_rotations(rotations, view0, view1, K, size_m, (AXIS_PEAKS, AXIS_SEPARATION_DEG), AXIS_PEAKS)


def _across(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """The part of `v` (..., 3) square to the unit `axis` (..., 3), as unit vectors (any square to it where `v` lies
    along it)."""
    w = v - np.sum(v * axis, axis=-1, keepdims=True) * axis
    n = np.linalg.norm(w, axis=-1, keepdims=True)
    helper = np.where(np.abs(axis[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    fallback = np.cross(axis, helper)
    fallback /= np.linalg.norm(fallback, axis=-1, keepdims=True)
    return np.where(n > 1e-9, w / np.maximum(n, 1e-12), fallback)
