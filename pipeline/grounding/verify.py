"""Check a motion hypothesis against both images: render-and-compare with the object clouds.

The initial object cloud, moved by the hypothesis, is projected into the goal view; each point that should be
visible (its normal faces the camera) either lands on the goal object at the observed depth (agreement; with the
observed colour too: colour agreement), lies in front of the observed surface (well in front, for a point of a
model's depth: CARVE_TOLS) or off the goal mask (contradiction), or lies behind it (occluded: no evidence); a point
the motion turns away from the camera is unseen, yet well in front of the observed surface it contradicts the view
too (free space). The same is done backwards, goal cloud into the initial view. The shares are the means of the two
directions: they separate the right motion from partial-view look-alikes that the feature consensus alone cannot
tell apart; geometry decides, colour breaks its ties (Agreement). A motion is judged (Agreement.whole) on the
turned-away points too: each must fall inside the other view's outline, behind what the camera sees there: a plate
turned over or a box tipped onto its seen face shows the goal camera none of the points first seen, and the seen
points alone leave a right motion with almost no evidence. It is judged on the direction that explains less: a small
object's cloud lies inside a large one's outline whatever the motion, so one direction alone can vouch for a pan
moved onto a tomato's mask.
How the colours the points bring correlate with those they land on (Agreement.pattern) is what tells a printed
object from its shape's twins (seen_turns.py): an editor's gain, offset and blur leave it unchanged.

The observed depth is matched within a tolerance no finer than the goal depth's own error (DEPTH_SIGMAS of it: a
model's depth is good to several millimetres, not to a sensor's one).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity

DEPTH_SIGMAS = 2.5  # depth agreement is no finer than this many standard errors of the goal depth
COLOUR_WEIGHT = 0.3  # colour's share of the ranking: a tie-break where geometry agrees within a few percent
MIN_PATTERN_POINTS = 20  # fewer points on the object than this say nothing about its print
FACING_COS = 0.1  # a point this far from grazing (cosine of its normal to its ray) faces toward or away from the camera
# a point turned away from the camera contradicts the view only this many depth tolerances in front of what it sees:
# a right motion's far side lies behind the seen surface by the object's thickness, except at the outline, where a
# model's depth bleeds toward the background. A point of a model's depth (the goal's, brought back) that faces the
# camera is held to the same margin in front of the surface it lands on: a model fills a hollow from its rim (a
# mug's inside floated 1-5 cm above its floor, and the right motion's points there contradicted the capture's
# measured floor)
CARVE_TOLS = 3.0
CHROMA_TOL = 0.06  # a point keeps its colour where its chromaticity lands this close to the one it brings


@dataclass(frozen=True)
class View:
    """One view's object: its cloud, normals and colours, and the images to compare against."""

    cloud: np.ndarray  # (N, 3) camera frame [m]
    normals: np.ndarray  # (N, 3) unit, facing the camera
    chroma: np.ndarray  # (N, 3) colour of each point
    depth: np.ndarray  # (H, W) metric, NaN invalid
    mask: np.ndarray  # (H, W) bool
    chroma_image: np.ndarray  # (H, W, 3)
    depth_sigma_m: float = 0.0  # standard error of `depth` (a model's goal depth; 0: a sensor's, negligible)

    @cached_property
    def extent_m(self) -> float:
        """The cloud's bounding-box diagonal [m]: no point of the object lies farther behind its seen surface."""
        return float(np.linalg.norm(self.cloud.max(axis=0) - self.cloud.min(axis=0))) if len(self.cloud) else 0.0

    def thinned(self, max_points: int) -> View:
        """The view with every k-th point at most `max_points` (the images whole): a coarse check needs the shape,
        not every point."""
        step = -(-len(self.cloud) // max_points)
        if step <= 1:
            return self
        return replace(self, cloud=self.cloud[::step], normals=self.normals[::step], chroma=self.chroma[::step])


def chromaticity(rgb: np.ndarray) -> np.ndarray:
    """Colour with brightness divided out (shading changes when an object turns)."""
    f = rgb.astype(np.float32)
    total = f[..., 0] + f[..., 1] + f[..., 2] + 30.0  # written out: numpy sums a length-3 last axis twenty times slower
    # divided channel by channel: broadcast over a length-3 last axis, numpy's inner loop takes three values at a time
    # (640 x 360: 1.3 vs 0.6 ms)
    for channel in range(3):
        np.divide(f[..., channel], total, out=f[..., channel])
    return f


def make_view(
    cloud: np.ndarray,
    chroma: np.ndarray,
    depth: np.ndarray,
    mask: np.ndarray,
    chroma_image: np.ndarray,
    voxel_m: float,
    depth_sigma_m: float = 0.0,
) -> View:
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cloud.astype(np.float64)))
    pcd.colors = o3d.utility.Vector3dVector(np.clip(chroma, 0, 1).astype(np.float64))
    pcd = pcd.voxel_down_sample(voxel_m)
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * voxel_m, max_nn=30))
    pcd.orient_normals_towards_camera_location(np.zeros(3))
    points, normals, colours = np.asarray(pcd.points), np.asarray(pcd.normals), np.asarray(pcd.colors)
    return View(points, normals, colours, depth, mask, chroma_image, depth_sigma_m)


@dataclass(frozen=True)
class Agreement:
    """How well a motion explains the views: `geometry`, the share of points that land on the other view's object at
    its depth; `colour`, the share that also keep their colour. Geometry decides: an editor's colour drift, its
    re-textured patches and a dark object's noisy chromaticity leave a right motion's colours unlike (a true motion's
    colour share was a median 0.27 on the raycast pairs, its geometry 0.8); colour breaks near-ties in geometry (a
    printed box turned half way, a label spun about a can)."""

    geometry: float
    colour: float
    pattern: float = 0.0  # the correlation of the colours the points bring with those they land on (-1..1)
    # the share of all points the views bear out, in the direction that explains less: `geometry`'s, and the
    # turned-away points inside the other view's outline behind what it sees (no farther than the object's size).
    # What a motion is judged on: a right motion that turns most seen points away keeps its evidence. Not what
    # motions are ranked on: every twin of a shape casts the same outline, which would dilute the seen points that
    # tell them apart
    whole: float = 0.0

    @property
    def ranked(self) -> float:
        """Geometry with colour as a tie-break: what hypotheses are ranked by."""
        return _ranked(self.geometry, self.colour)


def _ranked(geometry: np.ndarray | float, colour: np.ndarray | float) -> np.ndarray | float:
    """Agreement.ranked of geometric and colour shares, one motion's or many's."""
    return (1.0 - COLOUR_WEIGHT) * geometry + COLOUR_WEIGHT * colour


@dataclass(frozen=True)
class _Landing:
    """One direction's counts for each of M motions (M,): points that land on the object at its depth, of those that
    keep their colour, of the points that give evidence; and, per point of each moved cloud, the colour it lands on
    (NaN where it does not land on the object)."""

    on_object: np.ndarray
    same_colour: np.ndarray
    counted: np.ndarray
    found: np.ndarray  # (M, N, 3)
    outlined: np.ndarray  # turned-away points inside the outline, behind the seen surface
    outside: np.ndarray  # turned-away points off the outline or farther behind than the object is deep
    points: np.ndarray  # points facing or turned away from the camera, in front of it

    @property
    def share(self) -> np.ndarray:
        """The seen points' share that lands (Agreement.geometry)."""
        return self.on_object / self.counted

    @property
    def colour_share(self) -> np.ndarray:
        """The seen points' share that lands and keeps its colour (Agreement.colour)."""
        return self.same_colour / self.counted

    @property
    def whole_share(self) -> np.ndarray:
        """The share of all points the view bears out (Agreement.whole)."""
        # at least half of all the points count, as of the seen ones: a motion that hides the object under the
        # table or behind something else has no evidence against it either
        evidence = np.maximum(np.maximum(self.counted + self.outlined + self.outside, self.points // 2), 1)
        return (self.on_object + self.outlined) / evidence


def _landing(
    src: View, dst: View, motions: Sequence[Similarity], K: CameraIntrinsics, tol_m: float, chroma_tol: float
) -> _Landing:
    """src's points moved by each of the motions at once, as stacked (M, N) arrays with each point's part in the count
    masked in (not picked out motion by motion: the coarse check of ~60 hypotheses on 400 points, 18 -> 4 ms)."""
    scale = np.array([T.scale for T in motions])
    R = np.stack([T.R for T in motions]).transpose(0, 2, 1)
    X = scale[:, None, None] * src.cloud @ R + np.stack([T.t for T in motions])[:, None]  # as Similarity.apply
    facing = np.einsum("mij,mij->mi", src.normals @ R, X) / np.maximum(_length(X), 1e-9)
    z = X[..., 2]
    in_front = z > 1e-3
    # a surface point turned away from the camera cannot be seen, but it cannot float in front of what the camera
    # sees either: a ray through it meets the object there or nearer (free space carved). Without this a motion
    # scores by turning what it cannot explain away (a tray upside down, its floor facing off and floating)
    away = in_front & (facing > FACING_COS)
    keep = in_front & (facing < -FACING_COS)
    u, v, inside = image_pixels(K, np.where(in_front[..., None], X, 1.0))  # those behind the camera: never counted
    pixel = np.where(inside, v * K.width + u, 0)  # looked up by flat index: np.take, 4x faster than image[v, u]
    d, on_mask = np.take(dst.depth, pixel), np.take(dst.mask, pixel)
    carved, outlined, outside = _turned_away(z - d, on_mask, away & inside, away & ~inside, tol_m, scale * src.extent_m)
    points = np.count_nonzero(away | keep, axis=1)
    known = keep & inside & np.isfinite(d)
    on_object = known & on_mask & (np.abs(z - d) <= tol_m)
    silent = z > d + tol_m  # occluded
    if src.depth_sigma_m > 0:  # a model's points: in front is said only by the carve's margin
        silent |= on_mask & (z >= d - CARVE_TOLS * tol_m) & ~on_object
    motion, point = np.nonzero(on_object)
    there = np.take(dst.chroma_image.reshape(-1, 3), pixel[motion, point], axis=0)
    found = np.full(X.shape, np.nan)
    found[motion, point] = there
    same = np.bincount(motion[_length(there - src.chroma[point]) < chroma_tol], minlength=len(X))
    evidence = np.count_nonzero(known & ~silent, axis=1) + np.count_nonzero(keep & ~inside, axis=1) + carved
    # a hypothesis that hides most of the object behind the observed surface has little evidence either way:
    # count at least half of the camera-facing points so it cannot score by hiding
    counted = np.maximum(np.maximum(evidence, np.count_nonzero(keep, axis=1) // 2), 1)
    return _Landing(np.count_nonzero(on_object, axis=1), same, counted, found, outlined, outside, points)


def _length(v: np.ndarray) -> np.ndarray:
    """np.linalg.norm over a last axis of 3, written out in its order of sums, to the bit: 4x faster."""
    return np.sqrt(v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1] + v[..., 2] * v[..., 2])


def _turned_away(
    behind: np.ndarray, on_mask: np.ndarray, seen: np.ndarray, off_image: np.ndarray, tol_m: float, depth_m: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Of the points turned away from the camera, in the image where `seen` and off it where `off_image` (M, N), each
    `behind` the surface dst's depth sees along its ray and on dst's outline or not (`on_mask`), per motion (M,):
    (carved: more than CARVE_TOLS depth tolerances in front of that surface; outlined: the rest of those inside the
    outline, no more than the object's depth `depth_m` (M,) behind that surface; outside: off the image, or off the
    outline no farther than the tolerance behind what is seen there, or on it farther behind than the object is
    deep). NaN depth, or something else in front: no evidence."""
    depth_m = depth_m[:, None]
    carved = seen & (behind < -CARVE_TOLS * tol_m)  # NaN depth: every comparison false
    deep = behind > depth_m + tol_m
    outlined = seen & on_mask & ~carved & (behind <= depth_m + tol_m)
    stray = seen & ~on_mask & ~carved & (behind <= tol_m)
    outside = np.count_nonzero(seen & on_mask & deep, axis=1) + np.count_nonzero(stray, axis=1)
    return (
        np.count_nonzero(carved, axis=1),
        np.count_nonzero(outlined, axis=1),
        outside + np.count_nonzero(off_image, axis=1),
    )


def image_pixels(K: CameraIntrinsics, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, inside): the pixel each point (..., 3, in front of the camera) projects to, and whether it is in the
    image."""
    uv = np.round(K.project(X)).astype(int).reshape(*X.shape[:-1], 2)
    u, v = uv[..., 0], uv[..., 1]
    return u, v, (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)


def pattern_correlation(brought: np.ndarray, found: np.ndarray) -> float:
    """How well the colours points bring (N, 3) follow those they land on (N, 3, NaN where a point does not land on
    the object), -1..1: the correlation of the two, each centred on its mean, less one standard error (Fisher's z),
    so that a few points landing by chance on matching colours do not outrank many. A print turned the right way
    correlates whatever gain, offset or blur the editor gave the goal; turned the wrong way it does not; 0 where
    too few points land or either side has no contrast."""
    landed = np.isfinite(found[:, 0])
    if landed.sum() < MIN_PATTERN_POINTS:
        return 0.0
    a, b = brought[landed], found[landed]
    a, b = a - a.mean(axis=0), b - b.mean(axis=0)
    norm = float(np.sqrt((a * a).sum() * (b * b).sum()))
    if norm == 0:
        return 0.0
    r = float(np.clip((a * b).sum() / norm, -0.999, 0.999))
    return float(np.tanh(np.arctanh(r) - 1.0 / np.sqrt(len(a) - 3)))


def depth_tolerance(tol_m: float, *views: View) -> float:
    """`tol_m`, or DEPTH_SIGMAS standard errors of the views' depth where that is larger."""
    return max(tol_m, DEPTH_SIGMAS * max(v.depth_sigma_m for v in views))


def _both_ways(
    hypotheses: Sequence[Similarity], initial: View, goal: View, K: CameraIntrinsics, tol_m: float, chroma_tol: float
) -> tuple[_Landing, _Landing]:
    """Each hypothesis's landings initial -> goal and goal -> initial (moved back)."""
    tol_m = depth_tolerance(tol_m, initial, goal)
    inverses = [Similarity(1.0 / h.scale, h.R.T, -(h.R.T @ h.t) / h.scale) for h in hypotheses]
    fwd = _landing(initial, goal, hypotheses, K, tol_m, chroma_tol)
    return fwd, _landing(goal, initial, inverses, K, tol_m, chroma_tol)


def _geometry_colour(fwd: _Landing, bwd: _Landing) -> tuple[np.ndarray, np.ndarray]:
    """Agreement.geometry and Agreement.colour of each motion (M,): the shares of the two directions averaged."""
    return 0.5 * (fwd.share + bwd.share), 0.5 * (fwd.colour_share + bwd.colour_share)


def view_evidence(
    hypothesis: Similarity, initial: View, goal: View, K: CameraIntrinsics, tol_m: float, chroma_tol: float = CHROMA_TOL
) -> tuple[Agreement, np.ndarray]:
    """(view_consistency's agreement, the colour each point lands on: per point of the initial cloud moved by the
    hypothesis, then of the goal cloud moved back, NaN where it does not land on the object at its depth; in the
    order of brought_colours)."""
    return view_evidences([hypothesis], initial, goal, K, tol_m, chroma_tol)[0]


def view_evidences(
    hypotheses: Sequence[Similarity],
    initial: View,
    goal: View,
    K: CameraIntrinsics,
    tol_m: float,
    chroma_tol: float = CHROMA_TOL,
) -> list[tuple[Agreement, np.ndarray]]:
    """view_evidence of each of the hypotheses, all checked at once (a shape's 4-24 twins: 0.75 ms each alone)."""
    if not hypotheses:
        return []
    fwd, bwd = _both_ways(hypotheses, initial, goal, K, tol_m, chroma_tol)
    geometry, colour = _geometry_colour(fwd, bwd)
    whole, brought = np.minimum(fwd.whole_share, bwd.whole_share), brought_colours(initial, goal)
    out = []
    for k in range(len(hypotheses)):
        found = np.concatenate([fwd.found[k], bwd.found[k]])
        pattern = pattern_correlation(brought, found)
        out.append((Agreement(float(geometry[k]), float(colour[k]), pattern, float(whole[k])), found))
    return out


def view_consistency(
    hypothesis: Similarity, initial: View, goal: View, K: CameraIntrinsics, tol_m: float, chroma_tol: float = CHROMA_TOL
) -> Agreement:
    """Mean agreement shares (0..1) of initial -> goal and goal -> initial under the hypothesis; depths agree within
    `tol_m` or DEPTH_SIGMAS standard errors of the goal depth, whichever is larger."""
    return view_evidence(hypothesis, initial, goal, K, tol_m, chroma_tol)[0]


def ranked_consistency(
    hypotheses: Sequence[Similarity], initial: View, goal: View, K: CameraIntrinsics, tol_m: float
) -> np.ndarray:
    """view_consistency's Agreement.ranked of each of the hypotheses (M,), all checked at once."""
    if not hypotheses:
        return np.empty(0)
    return _ranked(*_geometry_colour(*_both_ways(hypotheses, initial, goal, K, tol_m, CHROMA_TOL)))


def brought_colours(initial: View, goal: View) -> np.ndarray:
    """The colours of both views' points, in the order view_evidence gives what they land on."""
    return np.concatenate([initial.chroma, goal.chroma])
