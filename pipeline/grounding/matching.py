"""Pixel correspondences from the initial object to the goal object, and their geometric filtering.

Matching follows the paper (cosine argmax of dense features), restricted to the goal mask, with a mutual
nearest-neighbour check and a similarity threshold. Filtering uses only what a rigid (or similarity) motion
preserves, distances between pairs of points, so objects that rotate in place keep their matches (the public
release drops every pair that moves less than 10 px instead).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.distance import cdist

from pipeline.perception.features import FeatureExtractor, best_matches


@dataclass(frozen=True)
class Matches:
    src_px: np.ndarray  # (N, 2) pixels of the initial image
    dst_px: np.ndarray  # (N, 2) pixels of the goal image
    similarity: np.ndarray  # (N,) cosine similarity


def match_pixels(
    features: FeatureExtractor,
    rgb0: np.ndarray,
    src_px: np.ndarray,
    rgb1: np.ndarray,
    dst_px: np.ndarray,
    points0: np.ndarray | None = None,
    points1: np.ndarray | None = None,
    *,
    mutual: bool = True,
    min_similarity: float = -1.0,
) -> Matches:
    """Argmax matches src_px -> dst_px (candidates), optionally mutual and above a similarity."""
    f0 = features.extract(rgb0, src_px, points0)
    f1 = features.extract(rgb1, dst_px, points1)
    idx, sim = best_matches(f0, f1)
    keep = sim >= min_similarity
    if mutual:  # only goal pixels some source pixel chose need their own best match: not every goal pixel
        chosen, slot = np.unique(idx, return_inverse=True)
        back, _ = best_matches(f1[chosen], f0)
        keep &= back[slot] == np.arange(len(src_px))
    return Matches(src_px[keep], dst_px[idx[keep]], sim[keep])


def pairwise_consistency(P: np.ndarray, Q: np.ndarray, tol_m: float, scale_range: tuple[float, float]) -> np.ndarray:
    """For each correspondence, the share of others whose mutual distance is preserved (within the scale range).

    Correct matches agree with each other; wrong ones agree only by chance. O(N^2): call with N <= ~2000.
    """
    dP, dQ = cdist(P, P), cdist(Q, Q)  # a tenth of the time of numpy's norm over a length-3 axis (1500: 6 vs 79 ms)
    lo, hi = scale_range
    agree = (dQ >= lo * dP - tol_m) & (dQ <= hi * dP + tol_m)
    np.fill_diagonal(agree, False)
    return agree.mean(axis=1) if len(P) > 1 else np.zeros(len(P))
