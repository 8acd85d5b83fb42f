"""Choosing the motion among hypotheses: a coarse view check ranks them all, the best few are refined by ICP
and checked again at a fine tolerance. The winner best explains both images (view agreement) while covering
the goal cloud (ICP fitness): it is ranked by the product of the two (colour breaking geometric ties) and judged
on geometry times fitness alone."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.grounding.refine import IcpTarget
from pipeline.grounding.types import GroundingConfig
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import Agreement, View, ranked_consistency, view_evidences
from pipeline.grounding.workers import workers

MAX_ICP_TURN_DEG = 15.0  # ICP may polish a hypothesis, not replace it
MAX_ICP_SHIFT_REL = 0.25
MIN_FITNESS = 0.3  # the share of either cloud with a counterpart in the other: below it the clouds do not meet
DRIFT_MARGIN = 0.1  # ICP that loses more fitness than this has drifted off
COARSE_POINTS = 400  # per view for the coarse cut: its shares to about 0.02
HINT_MARGIN = 0.02  # view agreement within this of the best: the views do not tell the motions apart


@dataclass(frozen=True)
class Selected:
    """The chosen motion and how well it explains the views: its fine view agreement and its ICP fitness (1 for a
    hint, which fitness does not rank)."""

    motion: Similarity
    agreement: Agreement
    fitness: float
    hinted: bool = False

    @property
    def score(self) -> float:
        """What refusal is judged on: geometric agreement over all points, the turned-away ones too (Agreement.whole),
        times fitness (colour drifts in an editor's goal)."""
        return self.agreement.whole * self.fitness

    @property
    def ranked(self) -> float:
        """What motions are compared on: geometry with colour as a tie-break, times fitness."""
        return self.agreement.ranked * self.fitness


def fine_tolerance(size: float, cfg: GroundingConfig) -> float:
    """The depth tolerance [m] refined motions are checked at: half the inlier threshold for an object of `size`."""
    return max(cfg.inlier_min_m, 0.5 * cfg.inlier_rel * size)


def select_motion(
    candidates: list[Similarity],
    view0: View,
    view1: View,
    K: CameraIntrinsics,
    size: float,
    cfg: GroundingConfig,
    hints: Sequence[Similarity] = (),
) -> Selected:
    """The best candidate after refinement, ranked by its view agreement (Agreement.ranked) times its ICP fitness,
    a hint by its view agreement alone.

    `hints` (motions known to be likely, such as the goal's when verifying) skip the coarse cut, are kept unpolished
    where ICP finds the clouds do not meet, and the best of them is taken when its view agreement is within
    HINT_MARGIN of the winner's: the views do not tell the two apart (a uniform box turned half way looks the same).
    ICP fitness does not rank hints: a turn that shows other faces loses fitness (the faces first seen turn out of
    view; a bottle stood up shows a side it lay on) that a twin keeping the seen faces in view does not."""
    coarse = max(cfg.inlier_min_m, 0.1 * size)
    thin0, thin1 = view0.thinned(COARSE_POINTS), view1.thinned(COARSE_POINTS)
    coarse_ranked = ranked_consistency(candidates, thin0, thin1, K, coarse)
    ranked = [candidates[k] for k in np.argsort(-coarse_ranked, kind="stable")[: cfg.refine_top]]
    fine = fine_tolerance(size, cfg)
    target = IcpTarget(view1.cloud, view1.normals) if cfg.icp else None

    def scored(hypotheses: Sequence[Similarity], keep: bool = False) -> list[Selected]:
        """Each hypothesis the clouds meet on (every one with `keep`, unpolished where they do not), refined two at a
        time (ICP and the tree searches leave the interpreter free), then checked at the fine tolerance all at once
        (8 hypotheses: 3.5 vs 6.3 ms one by one)."""

        def refined(hypothesis: Similarity) -> tuple[Similarity, float] | None:
            found = _refine(hypothesis, view0.cloud, target, size, cfg) if target else (hypothesis, 1.0)
            return (hypothesis, 0.0) if found is None and keep else found

        with workers() as pool:
            motions = [m for m in pool.map(refined, hypotheses) if m is not None]
        checked = view_evidences([sim for sim, _ in motions], view0, view1, K, fine)
        return [
            Selected(sim, agreement, fitness) for (sim, fitness), (agreement, _) in zip(motions, checked, strict=True)
        ]

    found, hinted = scored(ranked), scored(hints, keep=True)
    best = max(found, key=lambda s: s.ranked) if found else None
    if hinted:
        hint = max(hinted, key=lambda s: s.agreement.ranked)
        if best is None or hint.agreement.ranked >= best.agreement.ranked - HINT_MARGIN:
            return Selected(hint.motion, hint.agreement, 1.0, hinted=True)
    if best is None:
        return (
            Selected(ranked[0], Agreement(0.0, 0.0), 0.0)
            if ranked
            else Selected(hints[0], Agreement(0.0, 0.0), 0.0, True)
        )
    return best


def _refine(
    sim: Similarity, cloud0: np.ndarray, target: IcpTarget, size: float, cfg: GroundingConfig
) -> tuple[Similarity, float] | None:
    """(refined motion, fitness), the input kept when ICP wanders off or leaves the clouds meeting less than they
    did (point-to-plane ICP on a ball's or a can's surface is free to spin about its centre or axis and can drift
    off altogether: a ball put into a bowl met its goal on 89 % of its points as placed, on none after ICP), None
    when the clouds do not meet. The fitness is the larger share of either cloud with a counterpart in the other:
    a goal that shows an object in a bowl above the wall is all explained by the right motion, while only part of
    the capture's cloud can find a counterpart in it."""
    T0 = np.eye(4)
    T0[:3, :3], T0[:3, 3] = sim.R, sim.t
    max_corr = cfg.icp_max_corr_rel * size
    source = sim.scale * cloud0
    res = target.refine(source, T0, max_corr)
    refined = target.overlap(source @ res.T[:3, :3].T + res.T[:3, 3], max_corr)
    if refined < MIN_FITNESS or refined < 1.0 - DRIFT_MARGIN:  # else no placing can have met more by the margin
        placed = target.overlap(sim.apply(cloud0), max_corr)
        if refined < MIN_FITNESS or refined < placed - DRIFT_MARGIN:  # ICP made it worse: keep it as placed
            return (sim, placed) if placed >= MIN_FITNESS else None
    dR = res.T[:3, :3] @ sim.R.T
    angle = np.degrees(np.arccos(np.clip((np.trace(dR) - 1) / 2, -1, 1)))
    c = sim.scale * cloud0.mean(axis=0)
    shift = np.linalg.norm((res.T[:3, :3] @ c + res.T[:3, 3]) - (sim.R @ c + sim.t))
    if angle > MAX_ICP_TURN_DEG or shift > MAX_ICP_SHIFT_REL * size:
        return sim, refined
    return Similarity(sim.scale, res.T[:3, :3], res.T[:3, 3]), refined
