"""Affine alignment of a relative depth prediction to the metric depth of the initial view.

A monocular model predicts the goal view's depth only up to an unknown affine map, in its own output space:
depth-like models (metric heads, or anything linear in depth) or disparity-like ones (Depth Anything's
relative head is affine in inverse depth). The fit is made in that space, on background pixels only (the
complement of both object masks, a band along their edges and invalid pixels excluded: a monocular model bleeds
an object's edge into what lies behind it), robustly: a RANSAC over pixel pairs picks the consensus, then least
squares on its inliers. A model's prediction is also slowly warped by a few percent across the image, which no
global map absorbs (a 4 % warp leaves most of the background off by more than 1 %); what the affine map leaves on
the background, smoothed over a twentieth of the image (normalised convolution; over a fifth where an object
leaves too little background that close), is that warp, and is taken out everywhere, under the objects too, where
the surrounding background says what it is. A correction beyond MAX_WARP of the value is no warp but a wrong model
of the prediction, and is refused; one that barely lowers the background's residual (WARP_GAIN) is not made. The
residual is reported in metres so a caller can refuse.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import cv2
import numpy as np

EDGE_BAND_PX = 4  # background pixels this close to an object mask do not take part in the fit (bled edges)
CONSENSUS_REL = 0.06  # a pixel agrees with the global map within this share of its depth (before the warp is out)
WARP_SIGMA_REL = 0.05  # the warp is smoothed over this share of the image's width (a wave 0.6 wide keeps 87 %) ...
WARP_FILL_SIGMA_REL = 0.2  # ... and filled in over this share where little background is that close (large objects)
WARP_FILL_WEIGHT = 0.05  # (where the background's share within the first smoothing is under this)
WARP_WORK_PX = 80  # ... on an image this wide (it is smooth: a coarse grid holds it)
MAX_WARP = 0.08  # the largest correction a warp may make, as a share of the value it corrects
WARP_GAIN = 0.8  # a warp is taken out only where it leaves at most this share of the affine map's residual
SCOUT_SAMPLES = 2000  # pixels every RANSAC map is counted on ...
SCOUT_KEPT = 10  # ... and how many of the best there are counted on all

DepthKind = Literal["depth", "disparity"]


class DepthAlignmentError(ValueError):
    """The goal depth could not be put on the metric scale; the message says why, with the numbers."""


@dataclass(frozen=True)
class DepthAlignment:
    """metric = s * pred + b + warp (kind depth) or 1 / metric = s * pred + b + warp (kind disparity); warp is a
    smooth image (None: none was fitted) and `warp_max` its largest share of the value it corrects."""

    kind: DepthKind
    s: float
    b: float
    inlier_fraction: float
    residual_m: float  # median |metric - aligned prediction| on the background inliers [m]
    samples: int
    affine_residual_m: float = float("nan")  # the same before the warp was taken out
    warp_max: float = 0.0
    warp: np.ndarray | None = field(default=None, repr=False)

    def summary(self) -> dict:
        """The numbers, without the warp image (for records)."""
        return {k: v for k, v in self.__dict__.items() if k != "warp"}

    def apply(self, pred: np.ndarray) -> np.ndarray:
        """The prediction in metres (NaN where it maps to a non-positive depth)."""
        y = self.s * np.asarray(pred, dtype=np.float64) + self.b
        if self.warp is not None:
            y = y + self.warp
        if self.kind == "disparity":
            with np.errstate(divide="ignore", invalid="ignore"):
                y = np.where(y > 0, 1.0 / y, np.nan)
        else:
            y = np.where(y > 0, y, np.nan)
        return y.astype(np.float32)


def _target(depth_m: np.ndarray, kind: DepthKind) -> np.ndarray:
    return 1.0 / depth_m if kind == "disparity" else depth_m


def fit_depth_alignment(
    depth_m: np.ndarray,
    pred: np.ndarray,
    background: np.ndarray,
    kind: DepthKind = "depth",
    *,
    max_samples: int = 20000,
    iterations: int = 200,
    inlier_rel: float = 0.03,
    warp: bool = True,
    seed: int = 0,
) -> DepthAlignment:
    """Fit the affine map (and, with `warp`, the smooth warp) on `background` pixels where both maps are valid.

    `inlier_rel`: a pixel agrees with the fit when its aligned depth is within this fraction of its metric depth
    (3 %: a monocular model's ~1 % noise is 1 sigma; a sensor's is a fraction of it).
    """
    if kind not in ("depth", "disparity"):
        raise DepthAlignmentError(f"depth kind must be 'depth' or 'disparity', got {kind!r}")
    away = away_from_outline(background, EDGE_BAND_PX)
    valid_all = np.asarray(background, bool) & np.isfinite(depth_m) & (depth_m > 0) & np.isfinite(pred)
    valid = away & valid_all if (away & valid_all).sum() >= 50 else valid_all  # a thin background keeps its edges
    n_valid = int(valid.sum())
    if n_valid < 50:
        raise DepthAlignmentError(f"only {n_valid} valid background pixels to align the goal depth (need 50)")
    rng = np.random.default_rng(seed)
    sel = np.flatnonzero(valid)
    if len(sel) > max_samples:
        sel = rng.choice(sel, max_samples, replace=False)
    d = depth_m.reshape(-1)[sel].astype(np.float64)
    x = pred.reshape(-1)[sel].astype(np.float64)
    y = _target(d, kind)
    if np.ptp(x) <= 1e-12 * max(1.0, np.abs(x).max()):
        raise DepthAlignmentError("the goal depth prediction is constant on the background: nothing to align")
    consensus = max(inlier_rel, CONSENSUS_REL) if warp else inlier_rel
    s, b = _affine(x, y, d, kind, consensus, iterations, rng)
    affine = DepthAlignment(kind, s, b, 0.0, 0.0, len(x))
    inl = _agree(s, b, x, d, kind, inlier_rel)
    affine_residual = float(np.median(np.abs(affine.apply(x)[inl] - d[inl]))) if inl.any() else float("inf")
    fit = replace(
        affine, inlier_fraction=float(inl.mean()), residual_m=affine_residual, affine_residual_m=affine_residual
    )
    if not warp:
        return fit
    d_img = np.where(valid, depth_m, np.nan).astype(np.float64)
    y_img, x_img = _target(d_img, kind), pred.astype(np.float64)
    field_img = None
    for band_rel in (consensus, 2 * inlier_rel):  # the first field from the loose consensus, the second from its own
        base = s * x_img + b + (0.0 if field_img is None else field_img)
        with np.errstate(invalid="ignore", divide="ignore"):
            agree = valid & _agree_values(base, d_img, kind, band_rel)
        if agree.sum() < 50:
            break
        field_img = _smooth_residual(np.where(agree, y_img - s * x_img - b, 0.0), agree)
    if field_img is None:
        return fit
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.abs(field_img) / np.abs(s * x_img + b)
    warp_max = float(np.nanpercentile(share[valid], 99))
    if warp_max > MAX_WARP:  # no warp a model makes: leave it to the affine map's residual to refuse
        return replace(fit, warp_max=warp_max)
    warped = replace(affine, warp=field_img.astype(np.float32), warp_max=warp_max)
    aligned = warped.apply(pred).reshape(-1)[sel].astype(np.float64)
    inl = np.abs(aligned - d) < inlier_rel * d
    residual = float(np.median(np.abs(aligned[inl] - d[inl]))) if inl.any() else float("inf")
    if residual > WARP_GAIN * affine_residual:  # the prediction shows no warp worth taking out (a sensor's depth)
        return replace(fit, warp_max=warp_max)
    return replace(warped, inlier_fraction=float(inl.mean()), residual_m=residual, affine_residual_m=affine_residual)


def away_from_outline(mask: np.ndarray, px: int) -> np.ndarray:
    """The mask without a band of `px` pixels along its outline (the image's border is no outline)."""
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
    return cv2.erode(np.asarray(mask, np.uint8), kernel).astype(bool)


def _affine(
    x: np.ndarray, y: np.ndarray, d: np.ndarray, kind: DepthKind, rel: float, iterations: int, rng: np.random.Generator
) -> tuple[float, float]:
    """(s, b) of the map y = s x + b most pixels agree with within `rel` of their depth: RANSAC over pixel pairs,
    then least squares on the consensus, re-selected and refitted."""
    pairs = rng.integers(0, len(x), (iterations, 2))
    dx = x[pairs[:, 1]] - x[pairs[:, 0]]
    usable = np.abs(dx) > 1e-9 * max(1.0, np.abs(x).max())
    s_h = (y[pairs[usable, 1]] - y[pairs[usable, 0]]) / dx[usable]
    b_h = y[pairs[usable, 0]] - s_h * x[pairs[usable, 0]]
    # every pair's map counted on a random few thousand pixels at once, the best few on all: the same winner at a
    # fraction of the cost of counting every map on every sample
    scout = rng.choice(len(x), min(len(x), SCOUT_SAMPLES), replace=False)
    with np.errstate(invalid="ignore", divide="ignore"):
        counts = _agree_values(s_h[:, None] * x[scout] + b_h[:, None], d[scout], kind, rel).sum(axis=1)
    best_in, best_count = None, -1
    for k in np.sort(np.argsort(-counts, kind="stable")[:SCOUT_KEPT]):  # in drawing order: ties go as before
        s, b = s_h[k], b_h[k]
        inl = _agree(s, b, x, d, kind, rel)
        c = int(inl.sum())
        if c > best_count:
            best_count, best_in = c, inl
    if best_in is None or best_count < 10:
        raise DepthAlignmentError("no consistent affine map between goal prediction and metric background depth")
    s, b = 0.0, 0.0
    inl = best_in
    for _ in range(3):
        A = np.stack([x[inl], np.ones(int(inl.sum()))], axis=1)
        (s, b), *_ = np.linalg.lstsq(A, y[inl], rcond=None)
        inl_new = _agree(s, b, x, d, kind, rel)
        if inl_new.sum() < 10:
            break
        inl = inl_new
    return float(s), float(b)


def _smooth_residual(residual: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """The residual image smoothed where it is known and filled in where it is not (normalised convolution on a
    coarse grid): the warp, at full size."""
    h, w = residual.shape
    size = (WARP_WORK_PX, max(1, round(WARP_WORK_PX * h / w)))
    r = cv2.resize(residual.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    k = cv2.resize(weight.astype(np.float32), size, interpolation=cv2.INTER_AREA)

    def smoothed(sigma_rel: float) -> tuple[np.ndarray, np.ndarray]:
        sigma = sigma_rel * WARP_WORK_PX
        return cv2.GaussianBlur(r, (0, 0), sigma), cv2.GaussianBlur(k, (0, 0), sigma)

    (r1, k1), (r2, k2) = smoothed(WARP_SIGMA_REL), smoothed(WARP_FILL_SIGMA_REL)
    fine = r1 / np.maximum(k1, 1e-6)
    coarse = np.where(k2 > 1e-3, r2 / np.maximum(k2, 1e-3), 0.0)
    smooth = np.where(k1 >= WARP_FILL_WEIGHT, fine, coarse).astype(np.float32)
    return cv2.resize(smooth, (w, h), interpolation=cv2.INTER_LINEAR).astype(np.float64)


def _agree(s: float, b: float, x: np.ndarray, d: np.ndarray, kind: DepthKind, rel: float) -> np.ndarray:
    return _agree_values(s * x + b, d, kind, rel)


def _agree_values(y: np.ndarray, d: np.ndarray, kind: DepthKind, rel: float) -> np.ndarray:
    """Whether mapped values y (in the prediction's space) put the depth within `rel` of the metric depth d."""
    if kind == "disparity":
        # |1/y - d| < rel * d  <=>  |1 - y d| < rel * y d, for y > 0
        yd = y * d
        return (y > 0) & (np.abs(1.0 - yd) < rel * yd)
    return np.abs(y - d) < rel * d
