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


def test_closing_a_lid_composes_the_true_hinge_turn_and_grounding_recovers_it(lid_views):
    open_frame, _, lid_open, _, box_open, T_true = lid_views
    goal = build_reasoner(PipelineConfig()).run(open_frame, "close the blue box")
    assert goal.validated and goal.target == "lid of the blue box"
    assert (goal.mask_init & lid_open).sum() > 0.9 * lid_open.sum() and (goal.mask_init & box_open).sum() == 0
    assert (goal.mask_anchor & box_open).sum() > 0.9 * goal.mask_anchor.sum()
    points = open_frame.intrinsics.unproject_depth_image(open_frame.depth)[lid_open & np.isfinite(open_frame.depth)]
    centre = points.mean(axis=0)

    def error(R: np.ndarray, t: np.ndarray, T: np.ndarray) -> tuple[float, float]:
        moved = np.linalg.norm(R @ centre + t - (T[:3, :3] @ centre + T[:3, 3]))
        return float(moved), float(np.degrees(Rotation.from_matrix(R @ T[:3, :3].T).magnitude()))

    T_goal = goal.T_goal_init_camera
    composed_m, composed_deg = error(T_goal[:3, :3], T_goal[:3, 3], T_true)  # the editor shuts it as the sim does
    assert composed_m < 0.01 and composed_deg < 5.0, f"{composed_m * 1000:.1f} mm, {composed_deg:.1f} deg"
    motion = ground(GroundingInput.from_goal(open_frame, goal), make_feature_extractor("offline"))
    assert motion.ok, motion.reason
    grounded_m, grounded_deg = error(motion.R, motion.t, T_goal)
    assert grounded_m < 0.01 and grounded_deg < 5.0, f"{grounded_m * 1000:.1f} mm, {grounded_deg:.1f} deg"


def test_a_white_can_put_on_a_scales_white_plate_is_found_in_the_goal_among_what_the_edit_changed(
    sim_profile_with, tmp_path
):
    """In the goal image the can and the plate are one white region, which the scale's base names: the target is
    found among the pixels the edit changed, the goal is validated and grounding recovers the composed motion, up to
    a spin about the can's axis that no view shows (judged on the axis: its direction and a point on it)."""
    from drivers.sim import SimCamera, SimWorld
    from sim_helpers import write_can_and_scale

    profile = sim_profile_with({"sim": {"scene": write_can_and_scale(tmp_path / "scale.yaml")}})
    with SimCamera(SimWorld(profile.sim, profile.camera), seed=0) as camera:
        frame = camera.read().with_extrinsics(camera.T_base_camera)
    goal = build_reasoner(PipelineConfig()).run(frame, "put the white can on the light red scale")
    assert goal.validated
    accepted = goal.iterations[-1]
    assert any("found only among the pixels that changed" in c for c in accepted.checks), accepted.checks
    motion = ground(GroundingInput.from_goal(frame, goal), make_feature_extractor("offline"))
    assert motion.ok, motion.reason
    T = goal.T_goal_init_camera
    assert motion.symmetry.kind.startswith("revolution"), motion.symmetry.label
    on_axis, axis = motion.symmetry.centre, motion.symmetry.axis
    assert np.linalg.norm((motion.R @ on_axis + motion.t) - (T[:3, :3] @ on_axis + T[:3, 3])) < 0.015
    assert np.degrees(np.arccos(min(1.0, abs(float((motion.R @ axis) @ (T[:3, :3] @ axis)))))) < 5.0


def test_a_lid_of_its_chests_shade_drawn_shut_askew_is_found_in_the_goal(sim_profile_with, tmp_path):
    """The editor draws a shut lid of a shade of its chest's colour on the chest's top, offset from it: in the goal
    the lid face is the chest region's one large face, its lower edge no line across the box (the goal was refused
    three times: 'lid of the red box' missing from the candidate)."""
    from drivers.sim import SimCamera, SimWorld
    from sim_helpers import write_scene

    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.103, 0.154, 0.052], "xy_m": [0.6154, -0.0572]}
    chest |= {"yaw_deg": 17.81, "lid_open_deg": 104.9}
    path = write_scene(tmp_path / "chest.yaml", [chest])
    profile = sim_profile_with({"sim": {"scene": str(path)}})
    with SimCamera(SimWorld(profile.sim, profile.camera), seed=0) as camera:
        frame = camera.read().with_extrinsics(camera.T_base_camera)
        lid_open = camera.body_mask("chest_lid")
    goal = build_reasoner(PipelineConfig()).run(frame, "close the red box")
    assert goal.validated, [i.checks for i in goal.iterations]
    assert (goal.mask_init & lid_open).sum() > 0.8 * lid_open.sum()
    motion = ground(GroundingInput.from_goal(frame, goal), make_feature_extractor("offline"))
    assert motion.ok, motion.reason
