"""Least-squares similarity transforms (Umeyama 1991) and a RANSAC around them.

`dst ~ s R src + t`. The batched form solves thousands of minimal samples in one numpy call, which is what
makes a few thousand RANSAC hypotheses affordable on the CPU.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Similarity:
    """dst = scale * R @ src + t."""

    scale: float
    R: np.ndarray  # (3, 3)
    t: np.ndarray  # (3,)

    def apply(self, points: np.ndarray) -> np.ndarray:
        return self.scale * np.asarray(points) @ self.R.T + self.t

    def turned_first(self, g: np.ndarray, centre: np.ndarray) -> Similarity:
        """This motion after the object is first turned by g (3, 3) about `centre`: its twin under that turn."""
        return Similarity(self.scale, self.R @ g, self.scale * self.R @ (centre - g @ centre) + self.t)

    def turned_after(self, G: np.ndarray, point: np.ndarray) -> Similarity:
        """This motion followed by the turn G (3, 3) about `point` (where the motion puts things)."""
        return Similarity(self.scale, G @ self.R, G @ (self.t - point) + point)

    @property
    def matrix(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = self.scale * self.R
        T[:3, 3] = self.t
        return T


def umeyama_batch(src: np.ndarray, dst: np.ndarray, with_scale: bool = True) -> tuple[np.ndarray, ...]:
    """Solve (K, N, 3) correspondence sets at once -> scales (K,), rotations (K, 3, 3), translations (K, 3)."""
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    mu_s, mu_d = src.mean(axis=1), dst.mean(axis=1)
    xs, xd = src - mu_s[:, None], dst - mu_d[:, None]
    n = src.shape[1]
    cov = np.einsum("kni,knj->kij", xd, xs) / n
    U, S, Vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(U) * np.linalg.det(Vt))
    d[d == 0] = 1.0
    D = np.ones((len(d), 3))
    D[:, 2] = d
    R = np.einsum("kij,kj,kjl->kil", U, D, Vt)
    if with_scale:
        var_s = np.einsum("kni,kni->k", xs, xs) / n
        scale = np.einsum("ki,ki->k", S, D) / np.maximum(var_s, 1e-18)
    else:
        scale = np.ones(len(d))
    t = mu_d - scale[:, None] * np.einsum("kij,kj->ki", R, mu_s)
    return scale, R, t


def umeyama(src: np.ndarray, dst: np.ndarray, with_scale: bool = True) -> Similarity:
    """Best similarity (or rigid transform) mapping src (N, 3) onto dst (N, 3); needs N >= 3."""
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3 or len(src) < 3:
        raise ValueError(f"umeyama: need matching (N>=3, 3) arrays, got {src.shape} and {dst.shape}")
    s, R, t = umeyama_batch(src[None], dst[None], with_scale)
    return Similarity(float(s[0]), R[0], t[0])


@dataclass(frozen=True)
class RansacResult:
    transform: Similarity
    inliers: np.ndarray  # (N,) bool
    hypotheses: int  # non-degenerate minimal samples tried


def ransac_similarity(
    src: np.ndarray,
    dst: np.ndarray,
    threshold_m: float,
    *,
    with_scale: bool = True,
    iterations: int = 2000,
    min_sample_spread_m: float = 0.0,
    scale_range: tuple[float, float] = (0.0, np.inf),
    top_k: int = 1,
    seed: int = 0,
) -> list[RansacResult]:
    """RANSAC over 3-point samples; the `top_k` best distinct hypotheses, each refit on its inliers.

    Samples whose triangle is thinner than `min_sample_spread_m` are degenerate and skipped; hypotheses whose
    scale falls outside `scale_range` are discarded. Several hypotheses are returned because with ambiguous
    matches (symmetric or uniform objects) the largest consensus is not always the right motion: the caller
    can verify them against the images. Empty when no sample yields a hypothesis.
    """
    src = np.asarray(src, dtype=np.float64)
    dst = np.asarray(dst, dtype=np.float64)
    n = len(src)
    if n < 3:
        return []
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, n, (iterations, 3))
    a, b = src[idx], dst[idx]
    spread = _triangle_height(a)
    distinct = (idx[:, 0] != idx[:, 1]) & (idx[:, 1] != idx[:, 2]) & (idx[:, 0] != idx[:, 2])
    ok = distinct & (spread > 0) & (spread >= min_sample_spread_m)
    if not np.any(ok):
        return []
    s, R, t = umeyama_batch(a[ok], b[ok], with_scale)
    good = (s >= scale_range[0]) & (s <= scale_range[1])
    if not np.any(good):
        return []
    s, R, t = s[good], R[good], t[good]
    counts = np.empty(len(s), dtype=np.int64)
    for start in range(0, len(s), 512):  # bound memory: 512 hypotheses x N points at a time
        sl = slice(start, start + 512)
        off = s[sl, None, None] * np.einsum("kij,nj->kni", R[sl], src) + t[sl, None] - dst[None]
        counts[sl] = (np.einsum("kni,kni->kn", off, off) < threshold_m**2).sum(axis=1)
    results: list[RansacResult] = []
    for k in np.argsort(-counts, kind="stable")[: 20 * top_k]:
        if len(results) == top_k or counts[k] < 3:
            break
        transform = Similarity(float(s[k]), R[k], t[k])
        inliers = np.linalg.norm(transform.apply(src) - dst, axis=1) < threshold_m
        for _ in range(2):  # refit on the consensus set, re-score
            if inliers.sum() < 3:
                break
            transform = umeyama(src[inliers], dst[inliers], with_scale)
            inliers = np.linalg.norm(transform.apply(src) - dst, axis=1) < threshold_m
        if all(not _same(transform, r.transform, threshold_m) for r in results):
            results.append(RansacResult(transform, inliers, len(s)))
    return results


def _same(a: Similarity, b: Similarity, threshold_m: float) -> bool:
    dR = a.R @ b.R.T
    angle = np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1))
    return bool(angle < np.radians(10) and np.linalg.norm(a.t - b.t) < 3 * threshold_m)


def _triangle_height(tri: np.ndarray) -> np.ndarray:
    """Smallest height of each (K, 3, 3) triangle: near zero for coincident or collinear samples."""
    e = [tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 1], tri[:, 0] - tri[:, 2]]
    area2 = np.linalg.norm(np.cross(e[0], -e[2]), axis=1)
    longest = np.max(np.stack([np.linalg.norm(v, axis=1) for v in e]), axis=0)
    return area2 / np.maximum(longest, 1e-12)
