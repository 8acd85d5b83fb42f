"""What grounding compares: the two views of the object, made metric and comparable.

A generated goal differs from the capture in ways that say nothing about the motion, and each is taken out here,
on the background (what did not move), before any motion is looked for:
- its depth is a model's (unless measured, after execution): put on the capture's metric scale (depth_align),
  smoothed inside the object down to a sensor's noise (a model's per-pixel noise can be ~1 % of the depth, 5-10 mm
  at a metre, where the surface it stands for is smooth);
- its colours are an editor's: a gain and an offset per channel (and a light moved a little), fitted on the
  background and undone, so that colour compares like with like.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.grounding.depth_align import (
    EDGE_BAND_PX,
    DepthAlignment,
    DepthAlignmentError,
    away_from_outline,
    fit_depth_alignment,
)
from pipeline.grounding.types import GroundingConfig, GroundingInput, ObjectMotion
from pipeline.grounding.verify import View, chromaticity, make_view
from pipeline.grounding.workers import workers

SENSOR_NOISE_REL = 0.0015  # a depth camera's per-pixel noise / depth: a model's is smoothed down to it ...
MAX_SMOOTH_PX = 3.0  # ... over at most this many pixels (sigma); under MIN_SMOOTH_PX it is left as it is
MIN_SMOOTH_PX = 0.7
COLOUR_SAMPLES = 20000
COLOUR_FIT_ROUNDS = 3  # least squares, then refits without the pixels that changed (shadows, the object's old place)
# a table of one or two colours does not fix a gain: the fit leans to a gain of 1 unless the background's levels
# spread more than this (a least-squares gain fitted on a narrow range turned a grey plate blue)
GAIN_PRIOR_LEVELS = 25.0
HUE_BINS = 12
HUE_MIN_SATURATION = 0.15  # an object's mean saturation below this: too grey for its hue to be compared
HUE_MIN_VALUE = 40  # pixels darker than this (of 255) carry no hue


def object_size(points: np.ndarray) -> float:
    """Robust extent of a cloud [m]: the diagonal of its 5-95 percentile box."""
    lo, hi = np.percentile(points, [5, 95], axis=0)
    return float(np.linalg.norm(hi - lo))


def refuse(reason: str, **fields) -> ObjectMotion:
    return ObjectMotion(ok=False, reason=reason, **fields)


def align_goal_depth(
    inp: GroundingInput, cfg: GroundingConfig, T_base_camera: np.ndarray | None = None, what: str = ""
) -> tuple[np.ndarray, np.ndarray, DepthAlignment] | ObjectMotion:
    """(the capture's depth with holes as NaN, the goal depth aligned to it on the background, the alignment), or
    the refusal when the goal depth does not fit the scene; `what` prefixes the reason."""
    depth0 = np.where(np.isfinite(inp.depth0) & (inp.depth0 > 0), inp.depth0, np.nan).astype(np.float32)
    background = ~(inp.mask0 | inp.mask1)
    try:
        align = fit_depth_alignment(
            depth0, inp.depth1, background, inp.depth1_kind, warp=not inp.depth1_measured, seed=cfg.seed
        )
    except DepthAlignmentError as e:
        return refuse(f"{what}depth alignment failed: {e}")
    if align.inlier_fraction < cfg.min_background_inliers or align.residual_m > cfg.max_depth_residual_m:
        return refuse(
            f"{what}goal depth does not fit the scene: background residual {align.residual_m * 1000:.1f} mm "
            f"(limit {cfg.max_depth_residual_m * 1000:.0f}), inliers {align.inlier_fraction:.0%} "
            f"(need {cfg.min_background_inliers:.0%})",
            depth_residual_m=align.residual_m,
            T_base_camera=T_base_camera,
        )
    return depth0, align.apply(inp.depth1), align


def pixel_noise(depth: np.ndarray, where: np.ndarray) -> float:
    """Per-pixel noise of a depth image as a share of the depth: the robust spread of what a 2-pixel smoothing
    takes away, over `where` (the background, away from edges)."""
    known = where & np.isfinite(depth)
    if known.sum() < 50:
        return 0.0
    local = smooth_inside(depth, known, 2.0)
    rel = (depth[known] - local[known]) / depth[known]
    return float(1.4826 * np.median(np.abs(rel - np.median(rel))))


def smoothing_px(noise_rel: float) -> float:
    """The smoothing (Gaussian sigma, pixels) that brings per-pixel noise `noise_rel` down to a sensor's: 2-D
    noise averaged over sigma s shrinks about 2 sqrt(pi) s times; 0 when it is near a sensor's already (a
    smoothing rounds a small box's edges for nothing)."""
    sigma = noise_rel / (2.0 * np.sqrt(np.pi) * SENSOR_NOISE_REL)
    return 0.0 if sigma < MIN_SMOOTH_PX else float(min(sigma, MAX_SMOOTH_PX))


def goal_depth_error(depth0: np.ndarray, depth1: np.ndarray, where: np.ndarray, sigma_px: float) -> float:
    """Standard error [m] of the aligned goal depth as the object's is used (smoothed over sigma_px), measured on
    the background against the capture: what is left of the warp, the noise and the fit (robust: 1.4826 MAD)."""
    smooth = smooth_inside(depth1, where, sigma_px) if sigma_px > 0 else depth1
    known = where & np.isfinite(depth0) & np.isfinite(smooth)
    if known.sum() < 50:
        return 0.0
    return float(1.4826 * np.median(np.abs(smooth[known] - depth0[known])))


def smooth_inside(depth: np.ndarray, mask: np.ndarray, sigma_px: float) -> np.ndarray:
    """The depth smoothed over `sigma_px` using only pixels inside `mask` (normalised convolution), so the
    object's surface is not pulled toward what lies behind its outline; unchanged outside the mask."""
    inside = mask & np.isfinite(depth)
    if not inside.any():
        return depth
    w = inside.astype(np.float32)
    num = cv2.GaussianBlur(np.where(inside, depth, 0.0).astype(np.float32), (0, 0), sigma_px)
    den = cv2.GaussianBlur(w, (0, 0), sigma_px)
    with np.errstate(invalid="ignore", divide="ignore"):
        smooth = num / den
    return np.where(inside, smooth, depth).astype(np.float32)


def match_colours(rgb: np.ndarray, reference: np.ndarray, background: np.ndarray, seed: int = 0) -> np.ndarray:
    """`rgb` with a gain and offset per channel that make its background look like `reference`'s (float, 0-255),
    fitted robustly: pixels that changed between the two (shadows moved, the object's old and new places) are
    dropped after each round."""
    sel = np.flatnonzero(background)
    out = rgb.astype(np.float32)
    if len(sel) < 100:
        return out
    rng = np.random.default_rng(seed)
    if len(sel) > COLOUR_SAMPLES:
        sel = rng.choice(sel, COLOUR_SAMPLES, replace=False)
    x = rgb.reshape(-1, 3)[sel].astype(np.float64)
    y = reference.reshape(-1, 3)[sel].astype(np.float64)
    keep = np.ones(len(sel), bool)
    gains, offsets = np.ones(3), np.zeros(3)
    for _ in range(COLOUR_FIT_ROUNDS):
        xs, ys = x[keep], y[keep]
        mx, my = xs.mean(axis=0), ys.mean(axis=0)
        var, cov = ((xs - mx) ** 2).mean(axis=0), ((xs - mx) * (ys - my)).mean(axis=0)
        gains = (cov + GAIN_PRIOR_LEVELS**2) / (var + GAIN_PRIOR_LEVELS**2)  # a gain of 1 unless the colours vary
        offsets = my - gains * mx
        error = np.abs(x * gains + offsets - y)
        error = np.maximum(np.maximum(error[:, 0], error[:, 1]), error[:, 2])  # written out: max(axis=1), 25x faster
        keep = error <= max(3.0 * np.median(error), 1.0)
        if keep.sum() < 50:
            break
    # gains and offsets tiled along each image row: broadcast over a length-3 last axis, numpy's inner loop takes
    # three values at a time (640 x 360: 2.2 vs 0.5 ms)
    width = rgb.shape[1]
    gains, offsets = np.tile(gains.astype(np.float32), width), np.tile(offsets.astype(np.float32), width)
    return np.clip(out.reshape(len(out), -1) * gains + offsets, 0.0, 255.0).reshape(out.shape)


def hue_overlap(rgb0: np.ndarray, mask0: np.ndarray, rgb1: np.ndarray, mask1: np.ndarray) -> float | None:
    """How much the two objects' colours share (0..1): the intersection of their hue histograms, each pixel weighted
    by its saturation; None when either object is too grey or dark for hue to mean anything. An editor's drift, a
    re-textured patch or a turned print moves part of the hues; another object in the goal's mask (the red block
    become the blue one) moves all of them."""
    hists = []
    for rgb, mask in ((rgb0, mask0), (rgb1, mask1)):
        hsv = cv2.cvtColor(np.clip(rgb, 0, 255).astype(np.uint8)[mask][None], cv2.COLOR_RGB2HSV)[0].astype(np.float64)
        weight = np.where(hsv[:, 2] >= HUE_MIN_VALUE, hsv[:, 1] / 255.0, 0.0)
        if len(weight) == 0 or weight.mean() < HUE_MIN_SATURATION:
            return None
        # each pixel shared between its two nearest bins round the circle: hard bins put two hues a few degrees
        # apart on either side of an edge in no common bin (a red plate's 177 and, after the editor, 2: overlap 0)
        at = hsv[:, 0] * HUE_BINS / 180.0 - 0.5  # bins centred on whole numbers
        below = np.floor(at)
        share = at - below
        lo = below.astype(int) % HUE_BINS
        hist = np.bincount(lo, weight * (1.0 - share), HUE_BINS) + np.bincount(
            (lo + 1) % HUE_BINS, weight * share, HUE_BINS
        )
        hists.append(hist / hist.sum())
    return float(np.minimum(*hists).sum())


@dataclass(frozen=True)
class Prepared:
    """Both views of the object, metric and comparable, with what grounding needs besides."""

    depth0: np.ndarray  # the capture's depth, holes NaN
    depth1: np.ndarray  # the goal's, aligned (and smoothed inside the object)
    align: DepthAlignment
    points0: np.ndarray  # (H, W, 3) camera frame
    points1: np.ndarray
    valid0: np.ndarray  # object pixels lifted in each view
    valid1: np.ndarray
    size: float  # the object's extent [m]
    view0: View
    view1: View  # its depth_sigma_m: the error left in the goal depth (0 when measured)
    hue_overlap: float | None  # how much the objects' colours share (hue_overlap), None when too grey to tell

    @property
    def cloud0(self) -> np.ndarray:
        return self.points0[self.valid0]


def prepare(
    inp: GroundingInput, cfg: GroundingConfig, T_base_camera: np.ndarray | None = None
) -> Prepared | ObjectMotion:
    """The two views (for an input already at its working size), or the refusal, with its reason, when the goal
    depth does not fit the scene or either view has too few object pixels with depth."""
    background = ~(inp.mask0 | inp.mask1)
    with workers(1) as pool:  # the colours taken out alongside the depth
        colours = pool.submit(_colours, inp, background, cfg.seed)
        prepared = _prepare_depth(inp, cfg, background, T_base_camera)
        chroma0, rgb1, chroma1 = colours.result()
    if isinstance(prepared, ObjectMotion):
        return prepared
    depth0, depth1, error, align = prepared
    K = inp.intrinsics
    points0, points1 = K.unproject_depth_image(depth0), K.unproject_depth_image(depth1)
    valid0 = inp.mask0 & np.isfinite(depth0)
    valid1 = inp.mask1 & np.isfinite(depth1)
    if valid0.sum() < cfg.min_inliers or valid1.sum() < cfg.min_inliers:
        return refuse(
            f"too few object pixels with depth: {valid0.sum()} initial, {valid1.sum()} goal",
            depth_residual_m=align.residual_m,
            T_base_camera=T_base_camera,
        )
    cloud0 = points0[valid0]
    size = object_size(cloud0)
    voxel = max(cfg.icp_voxel_m, size / 40)
    view0 = make_view(cloud0, chroma0[valid0], depth0, inp.mask0, chroma0, voxel)
    view1 = make_view(points1[valid1], chroma1[valid1], depth1, inp.mask1, chroma1, voxel, error)
    hues = hue_overlap(inp.rgb0, inp.mask0, rgb1, inp.mask1)
    return Prepared(depth0, depth1, align, points0, points1, valid0, valid1, size, view0, view1, hues)


def _colours(inp: GroundingInput, background: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(the capture's chromaticity, the goal image with the editor's colour change undone, its chromaticity)."""
    rgb1 = match_colours(inp.rgb1, inp.rgb0, background, seed)
    return chromaticity(inp.rgb0), rgb1, chromaticity(rgb1)


def _prepare_depth(
    inp: GroundingInput, cfg: GroundingConfig, background: np.ndarray, T_base_camera: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, float, DepthAlignment] | ObjectMotion:
    """(the capture's depth, the goal's aligned to it and smoothed inside the object, the goal depth's standard error
    [m], the alignment), or the refusal when the goal depth does not fit the scene."""
    aligned = align_goal_depth(inp, cfg, T_base_camera)
    if isinstance(aligned, ObjectMotion):
        return aligned
    depth0, depth1, align = aligned
    error = 0.0
    if not inp.depth1_measured:  # a model's depth
        clear = away_from_outline(background, EDGE_BAND_PX)
        sigma = smoothing_px(pixel_noise(depth1, clear))
        error = goal_depth_error(depth0, depth1, clear, sigma)
        if sigma > 0:
            depth1 = smooth_inside(depth1, inp.mask1, sigma)
    return depth0, depth1, error, align
