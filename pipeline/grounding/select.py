"""Choosing the motion among hypotheses: a coarse view check ranks them all, the best few are refined by ICP
and checked again at a fine tolerance. The winner best explains both images (view agreement) while covering
the goal cloud (ICP fitness); the product of the two is its score."""

from __future__ import annotations

import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.grounding.refine import IcpTarget
from pipeline.grounding.types import GroundingConfig
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import View, view_consistency

MAX_ICP_TURN_DEG = 15.0  # ICP may polish a hypothesis, not replace it
MAX_ICP_SHIFT_REL = 0.25


def select_motion(
    candidates: list[Similarity], view0: View, view1: View, K: CameraIntrinsics, size: float, cfg: GroundingConfig
) -> tuple[float, Similarity]:
    """(view agreement, motion) of the best candidate after refinement."""
    coarse = max(cfg.inlier_min_m, 0.1 * size)
    ranked = sorted(candidates, key=lambda h: -view_consistency(h, view0, view1, K, coarse))[: cfg.refine_top]
    fine = max(cfg.inlier_min_m, 0.5 * cfg.inlier_rel * size)
    target = IcpTarget(view1.cloud, view1.normals) if cfg.icp else None
    scored = []
    for hypothesis in ranked:
        refined = _refine(hypothesis, view0.cloud, target, size, cfg) if target else (hypothesis, 1.0)
        if refined is not None:
            sim, fitness = refined
            scored.append((view_consistency(sim, view0, view1, K, fine) * fitness, sim))
    if not scored:
        return 0.0, ranked[0]
    return max(scored, key=lambda x: x[0])


def _refine(
    sim: Similarity, cloud0: np.ndarray, target: IcpTarget, size: float, cfg: GroundingConfig
) -> tuple[Similarity, float] | None:
    """(refined motion, ICP fitness), the input kept when ICP wanders off, None when the clouds do not meet."""
    T0 = np.eye(4)
    T0[:3, :3], T0[:3, 3] = sim.R, sim.t
    res = target.refine(sim.scale * cloud0, T0, cfg.icp_max_corr_rel * size)
    if res.fitness < 0.3:
        return None
    dR = res.T[:3, :3] @ sim.R.T
    angle = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    c = sim.scale * cloud0.mean(axis=0)
    shift = np.linalg.norm((res.T[:3, :3] @ c + res.T[:3, 3]) - (sim.R @ c + sim.t))
    if angle > MAX_ICP_TURN_DEG or shift > MAX_ICP_SHIFT_REL * size:
        return sim, res.fitness
    return Similarity(sim.scale, res.T[:3, :3], res.T[:3, 3]), res.fitness
