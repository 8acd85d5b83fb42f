"""The offline chain end to end: goals composed by stage 1 are recovered by spatial grounding within tolerance."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.config import PipelineConfig
from pipeline.grounding.ground import ground
from pipeline.grounding.types import GroundingInput
from pipeline.perception.features import make_feature_extractor
from pipeline.reasoning.factory import build_reasoner


@pytest.mark.parametrize(
    "instruction",
    ["put the red block on the white plate", "rotate the blue block by 40 degrees", "push the red block left by 8 cm"],
)
def test_grounding_recovers_the_composed_goal(sim_view, instruction):
    frame, _, _ = sim_view
    goal = build_reasoner(PipelineConfig()).run(frame, instruction)
    assert goal.validated
    inp = GroundingInput.from_goal(frame, goal)
    motion = ground(inp, make_feature_extractor("offline"))
    assert motion.ok, motion.reason
    points = frame.intrinsics.unproject_depth_image(frame.depth)[goal.mask_init]
    centroid = points[np.isfinite(points).all(axis=1)].mean(axis=0)
    T = goal.T_goal_init_camera
    error_m = np.linalg.norm((motion.R @ centroid + motion.t) - (T[:3, :3] @ centroid + T[:3, 3]))
    error_deg = np.degrees(Rotation.from_matrix(motion.R @ T[:3, :3].T).magnitude())
    assert error_m < 0.01 and error_deg < 5.0, f"{error_m * 100:.2f} cm, {error_deg:.2f} deg"
