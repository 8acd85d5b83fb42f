"""Motion hypotheses from the object clouds' geometry alone, to complement the feature consensus.

On uniform or symmetric objects feature matches are ambiguous and RANSAC may never sample the right motion.
Objects on a table mostly turn about the table normal and sometimes tip over, so a sweep of rotations
yaw(a) . tilt(theta) . yaw(b) about the normal, each with the translation that aligns the cloud centroids,
covers the likely motions at a coarse step; a vectorised silhouette check keeps the few worth refining.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity


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


def _mask_share(X: np.ndarray, normals: np.ndarray, closeness: np.ndarray, K: CameraIntrinsics) -> np.ndarray:
    """(M, N, 3) moved points and normals -> mean closeness to the mask of the camera-facing ones."""
    facing = np.einsum("mni,mni->mn", normals, X) < 0
    z = np.maximum(X[..., 2], 1e-3)
    u = np.round(K.fx * X[..., 0] / z + K.cx).astype(int)
    v = np.round(K.fy * X[..., 1] / z + K.cy).astype(int)
    inside = (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
    hit = np.zeros(inside.shape)
    hit[inside] = closeness[v[inside], u[inside]]
    return (hit * facing).sum(axis=1) / np.maximum(facing.sum(axis=1), 1)


def mask_closeness(mask: np.ndarray, sigma_px: float) -> np.ndarray:
    """1 on the mask, falling off as a Gaussian of the distance to it [px]: a soft silhouette."""
    import cv2

    d = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, 3)
    return np.exp(-((d / max(sigma_px, 0.5)) ** 2))


def silhouette_scores(
    rotations: np.ndarray,
    cloud0: np.ndarray,
    normals0: np.ndarray,
    closeness0: np.ndarray,
    cloud1: np.ndarray,
    normals1: np.ndarray,
    closeness1: np.ndarray,
    K: CameraIntrinsics,
) -> tuple[np.ndarray, np.ndarray]:
    """Score each rotation (with the translation that aligns the centroids): how close the camera-facing points
    land to the other view's silhouette (`closeness` maps), initial -> goal and goal -> initial. Returns
    scores (M,) and translations (M, 3)."""
    c0, c1 = cloud0.mean(axis=0), cloud1.mean(axis=0)
    X = np.einsum("mij,nj->mni", rotations, cloud0 - c0) + c1
    fwd = _mask_share(X, np.einsum("mij,nj->mni", rotations, normals0), closeness1, K)
    Y = np.einsum("mji,nj->mni", rotations, cloud1 - c1) + c0
    bwd = _mask_share(Y, np.einsum("mji,nj->mni", rotations, normals1), closeness0, K)
    t = c1 - np.einsum("mij,j->mi", rotations, c0)
    return 0.5 * (fwd + bwd), t


def sweep_hypotheses(
    cloud0: np.ndarray,
    normals0: np.ndarray,
    closeness0: np.ndarray,
    cloud1: np.ndarray,
    normals1: np.ndarray,
    closeness1: np.ndarray,
    K: CameraIntrinsics,
    up: np.ndarray,
    keep: int,
) -> list[Similarity]:
    """The `keep` best-scoring rotations of the sweep (closeness width ~ the expected centroid shift)."""
    rotations = rotation_sweep(up)
    scores, t = silhouette_scores(rotations, cloud0, normals0, closeness0, cloud1, normals1, closeness1, K)
    best = np.argsort(-scores)[:keep]
    return [Similarity(1.0, rotations[k], t[k]) for k in best]
