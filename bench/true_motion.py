"""The score main's grounding would give the true motion: ground()'s own preparation (prepare: goal depth aligned on
the background, object views) and selection (ICP polish, view agreement times ICP fitness) with each of the true
motion's twins (the same goal image, e.g. a can spun about its axis; or, under the shape's symmetry, the same
geometry, which is all ground()'s refusal judges before it reads a print) as its only hypothesis: the plain truth of
a spun can carries the seen side out of view, so only its best twin says what a right answer scores. ground()
refuses below GroundingConfig.min_view_score, so the share of true motions under it is the share of right answers
the refusal would throw away, whatever the search finds; what the truth ranks on against other hypotheses, beside
the answer's, tells a failure of the ranking from one of the search."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from bench.pairgen.generate import TrueSymmetry
from pipeline.grounding.prepare import prepare
from pipeline.grounding.select import select_motion
from pipeline.grounding.types import GroundingConfig, GroundingInput, ObjectMotion
from pipeline.grounding.umeyama import Similarity

SPIN_STEP_DEG = 10.0  # twins of a body of revolution: turns about its axis this far apart


def true_twins(
    T_true_camera: np.ndarray, truth: TrueSymmetry, R_camera_object0: np.ndarray, centre_camera: np.ndarray
) -> list[Similarity]:
    """The motions M g for the truth's turns g (object frame, about the object's centre), camera frame."""
    if truth.ball:
        turns = [np.eye(3), R_camera_object0.T @ T_true_camera[:3, :3].T @ R_camera_object0]  # the truth, a pure shift
    elif truth.axis is not None:
        a = truth.axis / np.linalg.norm(truth.axis)
        spins = Rotation.from_rotvec(np.outer(np.radians(np.arange(0.0, 360.0, SPIN_STEP_DEG)), a)).as_matrix()
        across = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        flip = Rotation.from_rotvec(np.pi * across / np.linalg.norm(across)).as_matrix()
        turns = [*spins, *(flip @ S for S in spins)] if truth.flip else list(spins)
    else:
        turns = list(truth.rotations)
    R_true, t_true = T_true_camera[:3, :3], T_true_camera[:3, 3]
    out = []
    for g in turns:
        R = R_true @ R_camera_object0 @ g @ R_camera_object0.T
        out.append(Similarity(1.0, R, R_true @ centre_camera + t_true - R @ centre_camera))
    return out


def true_motion_scores(inp: GroundingInput, twins: list[Similarity], cfg: GroundingConfig) -> tuple[float, float]:
    """(the view agreement ground() would refuse the best of the true motion's twins (true_twins) on, what the best
    of them would rank on against other hypotheses: select.Selected.score and .ranked, 0..1); zeros when ground()
    would refuse before scoring any motion (the goal depth does not fit the scene, too few object pixels)."""
    if cfg.work_width_px is not None and cfg.work_width_px < inp.intrinsics.width:
        inp = inp.resized(cfg.work_width_px)
    pp = prepare(inp, cfg)
    if isinstance(pp, ObjectMotion):
        return 0.0, 0.0
    # each twin on its own: ground()'s coarse ranking keeps only a few, and a look-alike twin may push out the one
    # that keeps the seen side in view
    selected = [select_motion([twin], pp.view0, pp.view1, inp.intrinsics, pp.size, cfg) for twin in twins]
    return max(float(s.score) for s in selected), max(float(s.ranked) for s in selected)
