"""ICP refinement (Open3D, point-to-plane, robust kernel) of a motion hypothesis on the masked object clouds."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


@dataclass(frozen=True)
class IcpResult:
    T: np.ndarray  # refined rigid transform (4x4) of the (pre-scaled) source onto the target
    fitness: float  # share of source points with a correspondence
    rmse_m: float


class IcpTarget:
    """The goal cloud with its normals, built once and reused for every hypothesis."""

    def __init__(self, points: np.ndarray, normals: np.ndarray) -> None:
        import open3d as o3d

        self.o3d = o3d
        self.points = points
        self.tree = cKDTree(points)
        self.pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        self.pcd.normals = o3d.utility.Vector3dVector(normals)

    def refine(self, source: np.ndarray, T_init: np.ndarray, max_corr_m: float, iterations: int = 20) -> IcpResult:
        """Point-to-plane ICP of source (N, 3) onto the target from T_init."""
        reg = self.o3d.pipelines.registration
        src = self.o3d.geometry.PointCloud(self.o3d.utility.Vector3dVector(source))
        result = reg.registration_icp(
            src,
            self.pcd,
            max_corr_m,
            T_init,
            reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=max_corr_m / 2)),
            reg.ICPConvergenceCriteria(max_iteration=iterations),
        )
        return IcpResult(np.asarray(result.transformation), float(result.fitness), float(result.inlier_rmse))

    def overlap(self, moved: np.ndarray, max_corr_m: float) -> float:
        """The larger share of either cloud within max_corr_m of the other: the moved source's (ICP's fitness) or the
        goal's. A goal that shows only part of the object (put into a bowl, its sides hidden by the wall) is all
        explained by the right motion, while only part of the source can find a counterpart in it."""
        # only whether a counterpart lies within max_corr_m counts: the search stops there (inf beyond), and a tree
        # used once is built unbalanced (faster to build, as fast to search a few thousand points)
        to_goal, _ = self.tree.query(moved, distance_upper_bound=max_corr_m)
        to_source, _ = cKDTree(moved, balanced_tree=False, compact_nodes=False).query(
            self.points, distance_upper_bound=max_corr_m
        )
        return max(float(np.mean(to_goal <= max_corr_m)), float(np.mean(to_source <= max_corr_m)))
