"""Affine alignment of a relative depth prediction to the metric depth of the initial view.

A monocular model predicts the goal view's depth only up to an unknown affine map, in its own output space:
depth-like models (metric heads, or anything linear in depth) or disparity-like ones (Depth Anything's
relative head is affine in inverse depth). The fit is made in that space, on background pixels only (the
complement of both object masks, invalid pixels excluded), robustly: a RANSAC over pixel pairs picks the
consensus, then least squares on its inliers. The residual is reported in metres so a caller can refuse.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

DepthKind = Literal["depth", "disparity"]


class DepthAlignmentError(ValueError):
    """The goal depth could not be put on the metric scale; the message says why, with the numbers."""


@dataclass(frozen=True)
class DepthAlignment:
    """metric = s * pred + b (kind depth) or 1 / metric = s * pred + b (kind disparity)."""

    kind: DepthKind
    s: float
    b: float
    inlier_fraction: float
    residual_m: float  # median |metric - aligned prediction| on the background inliers [m]
    samples: int

    def apply(self, pred: np.ndarray) -> np.ndarray:
        """The prediction in metres (NaN where it maps to a non-positive depth)."""
        y = self.s * np.asarray(pred, dtype=np.float64) + self.b
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
    inlier_rel: float = 0.01,
    seed: int = 0,
) -> DepthAlignment:
    """Fit the affine map on `background` pixels where both maps are valid.

    `inlier_rel`: a pixel agrees with a hypothesis when its aligned depth is within this fraction of its
    metric depth (1 % = 1 cm at 1 m, several sensor sigmas).
    """
    if kind not in ("depth", "disparity"):
        raise DepthAlignmentError(f"depth kind must be 'depth' or 'disparity', got {kind!r}")
    valid = background & np.isfinite(depth_m) & (depth_m > 0) & np.isfinite(pred)
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

    pairs = rng.integers(0, len(x), (iterations, 2))
    dx = x[pairs[:, 1]] - x[pairs[:, 0]]
    usable = np.abs(dx) > 1e-9 * max(1.0, np.abs(x).max())
    s_h = (y[pairs[usable, 1]] - y[pairs[usable, 0]]) / dx[usable]
    b_h = y[pairs[usable, 0]] - s_h * x[pairs[usable, 0]]
    best_in, best_count = None, -1
    for s, b in zip(s_h, b_h, strict=True):
        inl = _agree(s, b, x, d, kind, inlier_rel)
        c = int(inl.sum())
        if c > best_count:
            best_count, best_in = c, inl
    if best_in is None or best_count < 10:
        raise DepthAlignmentError("no consistent affine map between goal prediction and metric background depth")
    s, b = 0.0, 0.0
    inl = best_in
    for _ in range(3):  # least squares on the consensus, re-select, refit
        A = np.stack([x[inl], np.ones(int(inl.sum()))], axis=1)
        (s, b), *_ = np.linalg.lstsq(A, y[inl], rcond=None)
        inl_new = _agree(s, b, x, d, kind, inlier_rel)
        if inl_new.sum() < 10:
            break
        inl = inl_new
    aligned = DepthAlignment(kind, float(s), float(b), 0.0, 0.0, len(x)).apply(x)
    resid = np.abs(aligned[inl] - d[inl])
    return DepthAlignment(kind, float(s), float(b), float(inl.mean()), float(np.median(resid)), len(x))


def _agree(s: float, b: float, x: np.ndarray, d: np.ndarray, kind: DepthKind, rel: float) -> np.ndarray:
    y = s * x + b
    if kind == "disparity":
        # |1/y - d| < rel * d  <=>  |1 - y d| < rel * y d, for y > 0
        yd = y * d
        return (y > 0) & (np.abs(1.0 - yd) < rel * yd)
    return np.abs(y - d) < rel * d
