"""The paper's grounding recipe as its public release implements it, for side-by-side benchmarks.

Written from the description in ../shared/reference/method-notes.md (not from the release's code):
- both images resized to 200x200; a 60x60 feature grid on the goal; 1000 source pixels sampled on the
  initial mask; one-way cosine argmax over the whole goal grid, no mutual check, no threshold;
- pairs moving 10 px or less (in the 200x200 image) dropped;
- the goal depth passed through an 8-bit picture normalised per image, then a single least-squares
  (s, b) fitted on the whole image (object pixels included, depth > 0.5 m) in the depth space;
- rigid Kabsch (no scale) in RANSAC: 2000 iterations, 3-point samples, 3 cm inlier threshold, refit.
Same ObjectMotion output as ours, so the benchmark scores both identically.
"""

from __future__ import annotations

import numpy as np

from pipeline.grounding.types import GroundingInput, ObjectMotion
from pipeline.grounding.umeyama import ransac_similarity
from pipeline.perception.features import FeatureExtractor, best_matches

WORK_SIZE = 200
GRID = 60
SOURCE_PIXELS = 1000
MIN_DISPLACEMENT_PX = 10.0
INLIER_M = 0.03


def ground_baseline(inp: GroundingInput, features: FeatureExtractor, seed: int = 0) -> ObjectMotion:
    K = inp.intrinsics
    W, H = K.width, K.height
    sx, sy = WORK_SIZE / W, WORK_SIZE / H
    depth0 = np.where(np.isfinite(inp.depth0) & (inp.depth0 > 0), inp.depth0, np.nan)
    pred = _as_8bit(inp.depth1)
    fit_px = np.isfinite(depth0) & (depth0 > 0.5) & np.isfinite(pred)
    A = np.stack([pred[fit_px], np.ones(int(fit_px.sum()))], axis=1)
    (s, b), *_ = np.linalg.lstsq(A, depth0[fit_px], rcond=None)
    depth1 = s * pred + b
    rng = np.random.default_rng(seed)
    src = np.argwhere(inp.mask0 & np.isfinite(depth0))[:, ::-1]
    if len(src) == 0:
        return ObjectMotion(ok=False, reason="no object pixel with depth")
    src = src[rng.choice(len(src), min(SOURCE_PIXELS, len(src)), replace=False)]
    # goal candidates: the 60x60 grid cell centres of the 200x200 image, mapped back to full-resolution pixels
    g = (np.arange(GRID) + 0.5) * WORK_SIZE / GRID - 0.5
    gu, gv = np.meshgrid(g, g)
    dst = np.stack([(gu.ravel() + 0.5) / sx - 0.5, (gv.ravel() + 0.5) / sy - 0.5], axis=1)
    points0 = K.unproject_depth_image(depth0.astype(np.float32))
    points1 = K.unproject_depth_image(depth1.astype(np.float32))
    idx, _ = best_matches(features.extract(inp.rgb0, src, points0), features.extract(inp.rgb1, dst, points1))
    matched = dst[idx]
    moved = np.hypot((matched[:, 0] - src[:, 0]) * sx, (matched[:, 1] - src[:, 1]) * sy) > MIN_DISPLACEMENT_PX
    src, matched = src[moved], matched[moved]
    mu, mv = (
        np.clip(np.round(matched[:, 0]).astype(int), 0, W - 1),
        np.clip(np.round(matched[:, 1]).astype(int), 0, H - 1),
    )
    P = points0[src[:, 1], src[:, 0]]
    Q = K.unproject(matched, depth1[mv, mu])
    ok = np.all(np.isfinite(P), axis=1) & np.all(np.isfinite(Q), axis=1)
    P, Q = P[ok], Q[ok]
    fits = ransac_similarity(P, Q, INLIER_M, with_scale=False, iterations=2000, seed=seed)
    if not fits:
        return ObjectMotion(ok=False, reason=f"no rigid hypothesis from {len(P)} matches", matches=len(P))
    fit = fits[0]
    n_in = int(fit.inliers.sum())
    resid = np.linalg.norm(fit.transform.apply(P[fit.inliers]) - Q[fit.inliers], axis=1)
    return ObjectMotion(
        ok=True,
        reason="",
        R=fit.transform.R,
        t=fit.transform.t,
        inliers=n_in,
        matches=len(P),
        residual_m=float(np.sqrt(np.mean(resid**2))) if n_in else float("nan"),
    )


def _as_8bit(pred: np.ndarray) -> np.ndarray:
    """Per-image min-max normalisation to 0..255 and rounding, as the release stores its depth pictures."""
    finite = np.isfinite(pred)
    lo, hi = float(pred[finite].min()), float(pred[finite].max())
    out = np.full(pred.shape, np.nan)
    out[finite] = np.round((pred[finite] - lo) / max(hi - lo, 1e-12) * 255.0)
    return out
