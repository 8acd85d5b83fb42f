"""The score main's grounding would give the true motion: ground()'s own preparation (goal depth aligned on the
background, object views) and selection (ICP polish, view agreement times ICP fitness) with the true motion as the
only hypothesis. ground() refuses below GroundingConfig.min_view_score, so the share of true motions under it is
the share of right answers the refusal would throw away, whatever the search finds."""

from __future__ import annotations

import numpy as np

from pipeline.grounding.depth_align import DepthAlignmentError, fit_depth_alignment
from pipeline.grounding.ground import object_size
from pipeline.grounding.select import select_motion
from pipeline.grounding.types import GroundingConfig, GroundingInput
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import chromaticity, make_view


def true_motion_agreement(inp: GroundingInput, T_true_camera: np.ndarray, cfg: GroundingConfig) -> float:
    """View agreement (0..1) of the true motion x_goal = T x_init (camera frame); 0 when ground() would refuse
    before scoring any motion (the goal depth does not fit the scene, too few object pixels)."""
    if cfg.work_width_px is not None and cfg.work_width_px < inp.intrinsics.width:
        inp = inp.resized(cfg.work_width_px)
    K = inp.intrinsics
    depth0 = np.where(np.isfinite(inp.depth0) & (inp.depth0 > 0), inp.depth0, np.nan).astype(np.float32)
    try:
        align = fit_depth_alignment(depth0, inp.depth1, ~(inp.mask0 | inp.mask1), inp.depth1_kind, seed=cfg.seed)
    except DepthAlignmentError:
        return 0.0
    if align.inlier_fraction < cfg.min_background_inliers or align.residual_m > cfg.max_depth_residual_m:
        return 0.0
    depth1 = align.apply(inp.depth1)
    points0, points1 = K.unproject_depth_image(depth0), K.unproject_depth_image(depth1)
    valid0, valid1 = inp.mask0 & np.isfinite(depth0), inp.mask1 & np.isfinite(depth1)
    if valid0.sum() < cfg.min_inliers or valid1.sum() < cfg.min_inliers:
        return 0.0
    cloud0 = points0[valid0]
    size = object_size(cloud0)
    chroma0, chroma1 = chromaticity(inp.rgb0), chromaticity(inp.rgb1)
    voxel = max(cfg.icp_voxel_m, size / 40)
    view0 = make_view(cloud0, chroma0[valid0], depth0, inp.mask0, chroma0, voxel)
    view1 = make_view(points1[valid1], chroma1[valid1], depth1, inp.mask1, chroma1, voxel)
    truth = Similarity(1.0, T_true_camera[:3, :3], T_true_camera[:3, 3])
    score, _ = select_motion([truth], view0, view1, K, size, cfg)
    return float(score)
