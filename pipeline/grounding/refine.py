"""Optional ICP refinement (Open3D, point-to-plane) of a registration on the masked object clouds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class IcpResult:
    T: np.ndarray  # refined rigid transform (4x4) of the (pre-scaled) source onto the target
    fitness: float  # share of source points with a correspondence
    rmse_m: float


def icp_refine(
    source: np.ndarray, target: np.ndarray, T_init: np.ndarray, max_corr_m: float, voxel_m: float
) -> IcpResult | None:
    """Point-to-plane ICP of source (N, 3) onto target (M, 3) from T_init; None if the clouds are too small."""
    import open3d as o3d

    reg = o3d.pipelines.registration
    src = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(source)).voxel_down_sample(voxel_m)
    dst = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(target)).voxel_down_sample(voxel_m)
    if len(src.points) < 20 or len(dst.points) < 20:
        return None
    dst.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=4 * voxel_m, max_nn=30))
    dst.orient_normals_towards_camera_location(np.zeros(3))
    result = reg.registration_icp(
        src,
        dst,
        max_corr_m,
        T_init,
        reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=max_corr_m / 2)),
        reg.ICPConvergenceCriteria(max_iteration=20),
    )
    return IcpResult(np.asarray(result.transformation), float(result.fitness), float(result.inlier_rmse))
