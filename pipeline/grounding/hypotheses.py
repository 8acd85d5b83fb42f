"""Motion hypotheses from the object clouds' geometry alone, to complement the feature consensus.

On uniform or symmetric objects feature matches are ambiguous and RANSAC may never sample the right motion.
Objects on a table mostly turn about the table normal and sometimes tip over, so a sweep of rotations
yaw(a) . tilt(theta) . yaw(b) about the normal, each with the translation that aligns the cloud centroids,
covers the likely motions at a coarse step. A vectorised render-and-compare check (soft silhouette, depth and
colour agreement at a coarse tolerance, both ways) keeps the few worth refining.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View

MAX_POINTS = 200  # per cloud: a coarse check needs the shape, not every point
CHROMA_SIGMA = 0.08
SILHOUETTE_SIGMA_REL = 0.1  # soft-silhouette width / object size
DEPTH_TOL_REL = 0.15  # depth agreement width / object size


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
    """(M, N, 3) moved points -> mean soft agreement (silhouette x depth x colour) of the camera-facing, not
    occluded ones with the other view."""
    facing = np.einsum("mni,mni->mn", normals, X) < 0
    z = np.maximum(X[..., 2], 1e-3)
    u = np.round(K.fx * X[..., 0] / z + K.cx).astype(int)
    v = np.round(K.fy * X[..., 1] / z + K.cy).astype(int)
    inside = (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    u, v = np.where(inside, u, 0), np.where(inside, v, 0)
    d = other.depth[v, u]
    seen = np.isfinite(d)
    d = np.where(seen, d, z)
    counted = facing & (~inside | ~seen | (z < d + tol_m))  # points behind the observed surface: no evidence
    colour = np.exp(-np.sum((other.chroma_image[v, u] - chroma[None]) ** 2, axis=-1) / CHROMA_SIGMA**2)
    hit = inside * closeness[v, u] * np.exp(-(((z - d) / tol_m) ** 2)) * colour
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
    c0, c1 = view0.cloud.mean(axis=0), view1.cloud.mean(axis=0)
    s0, s1 = max(1, len(view0.cloud) // MAX_POINTS), max(1, len(view1.cloud) // MAX_POINTS)
    p0, n0, k0 = view0.cloud[::s0], view0.normals[::s0], view0.chroma[::s0]
    p1, n1, k1 = view1.cloud[::s1], view1.normals[::s1], view1.chroma[::s1]
    X = np.einsum("mij,nj->mni", rotations, p0 - c0) + c1
    fwd = _agreement(X, np.einsum("mij,nj->mni", rotations, n0), k0, view1, closeness1, K, tol_m)
    Y = np.einsum("mji,nj->mni", rotations, p1 - c1) + c0
    bwd = _agreement(Y, np.einsum("mji,nj->mni", rotations, n1), k1, view0, closeness0, K, tol_m)
    t = c1 - np.einsum("mij,j->mi", rotations, c0)
    return 0.5 * (fwd + bwd), t


def sweep_hypotheses(
    view0: View, view1: View, K: CameraIntrinsics, up: np.ndarray, keep: int, size_m: float
) -> list[Similarity]:
    """The `keep` best rotations of the sweep; tolerances scale with the object (the centroids of two partial
    views can differ by a good part of its size)."""
    sigma_px = SILHOUETTE_SIGMA_REL * size_m * K.fx / float(np.median(view0.cloud[:, 2]))
    closeness0 = mask_closeness(view0.mask, sigma_px)
    closeness1 = mask_closeness(view1.mask, sigma_px)
    rotations = rotation_sweep(up)
    scores, t = coarse_scores(rotations, view0, view1, closeness0, closeness1, K, DEPTH_TOL_REL * size_m)
    best = np.argsort(-scores)[:keep]
    return [Similarity(1.0, rotations[k], t[k]) for k in best]
