"""ground() on pairs rendered in the simulator with known motions, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest
from grounding_helpers import errors, goal_pose

from pipeline.grounding.baseline import ground_baseline
from pipeline.grounding.ground import ground
from pipeline.grounding.types import GroundingInput
from pipeline.perception.offline_features import OfflineFeatures

FEATURES = OfflineFeatures()


def _input(pair, **replace) -> GroundingInput:
    fields = {
        "rgb0": pair.rgb0,
        "depth0": pair.depth0,
        "mask0": pair.mask0,
        "rgb1": pair.rgb1,
        "depth1": pair.depth1,
        "depth1_kind": pair.depth1_kind,
        "mask1": pair.mask1,
        "intrinsics": pair.intrinsics,
    }
    return GroundingInput(**{**fields, **replace})


@pytest.fixture(scope="module")
def pan_pair(pair_renderer):
    goal = goal_pose(pair_renderer, "pan_a", (-0.05, -0.10), 70.0)
    return pair_renderer.render("pan_a", goal, "disparity", np.random.default_rng(0))


def test_pan_shift_and_turn_is_recovered(pan_pair):
    motion = ground(_input(pan_pair), FEATURES, T_base_camera=pan_pair.T_base_camera)
    assert motion.ok, motion.reason
    t_err, r_err, _ = errors(pan_pair, motion)
    assert t_err < 8.0 and r_err < 3.0, (t_err, r_err)
    assert motion.scale == pytest.approx(1.0, abs=0.1)
    np.testing.assert_allclose(
        motion.T_base, pan_pair.T_base_camera @ motion.T_camera @ np.linalg.inv(pan_pair.T_base_camera)
    )


def test_half_resolution_gives_the_same_motion(pan_pair):
    """Intrinsics follow the resize (pixel-centre convention): the motion does not depend on the working size."""
    from pipeline.grounding.types import GroundingConfig

    full = ground(_input(pan_pair), FEATURES)
    half = ground(_input(pan_pair), FEATURES, GroundingConfig(work_width_px=320))
    assert full.ok and half.ok, (full.reason, half.reason)
    t_err, r_err, _ = errors(pan_pair, half)
    assert t_err < 10.0 and r_err < 4.0, (t_err, r_err)
    c = pan_pair.centre_camera  # where both put the object's centre (t alone mixes in the rotation's lever)
    assert np.linalg.norm((full.R @ c + full.t) - (half.R @ c + half.t)) < 0.008


def test_in_place_rotation_is_kept(pair_renderer):
    """A pure turn: most pixels barely move, which the release's 10 px cut would throw away."""
    pair = pair_renderer.render(
        "box_a", goal_pose(pair_renderer, "box_a", (0.0, 0.0), 35.0), "depth", np.random.default_rng(1)
    )
    motion = ground(_input(pair), FEATURES)
    assert motion.ok, motion.reason
    t_err, _, a_err = errors(pair, motion)
    assert t_err < 5.0 and a_err < 3.0, (t_err, a_err)


def test_bottle_stand_up_axis(pair_renderer):
    """Lying bottle stood up (90 deg tilt): the bottle axis is what the task needs."""
    name = "bottle_a"
    T0 = pair_renderer.world.object_pose(name)
    goal = goal_pose(pair_renderer, name, (-0.08, 0.05), 0.0, 0.0)
    from scipy.spatial.transform import Rotation

    stand = Rotation.from_rotvec([0.0, -np.pi / 2, 0.0]).as_matrix()  # body x (the lying axis) -> up
    goal[:3, :3] = T0[:3, :3] @ stand
    pair = pair_renderer.render(name, goal, "disparity", np.random.default_rng(2))
    assert pair is not None
    motion = ground(_input(pair), FEATURES, T_base_camera=pair.T_base_camera)
    assert motion.ok, motion.reason
    M = pair.T_motion_camera
    axis = pair.T_camera_object0[:3, 0]
    a_err = np.degrees(np.arccos(np.clip(np.dot(motion.R @ axis, M[:3, :3] @ axis), -1, 1)))
    t_err = 1000 * np.linalg.norm(
        (motion.R @ pair.centre_camera + motion.t) - (M[:3, :3] @ pair.centre_camera + M[:3, 3])
    )
    assert a_err < 5.0 and t_err < 10.0, (a_err, t_err)


def test_ours_beats_the_release_recipe_on_a_turn(pan_pair):
    ours = errors(pan_pair, ground(_input(pan_pair), FEATURES))
    paper = ground_baseline(_input(pan_pair), FEATURES)
    theirs = errors(pan_pair, paper) if paper.ok else (np.inf, np.inf, np.inf)
    assert ours[0] < theirs[0] and ours[1] < theirs[1]


def test_refuses_goal_depth_that_does_not_fit_the_scene(pan_pair):
    noise = np.random.default_rng(3).uniform(0, 1, pan_pair.depth1.shape).astype(np.float32)
    motion = ground(_input(pan_pair, depth1=noise), FEATURES)
    assert not motion.ok
    assert "goal depth" in motion.reason or "alignment" in motion.reason


def test_refuses_a_goal_mask_with_almost_no_pixels(pan_pair):
    tiny = np.zeros_like(pan_pair.mask1)
    v, u = np.argwhere(pan_pair.mask1)[len(np.argwhere(pan_pair.mask1)) // 2]
    tiny[v : v + 2, u : u + 2] = True
    motion = ground(_input(pan_pair, mask1=tiny), FEATURES)
    assert not motion.ok and "too few" in motion.reason


def test_refuses_when_the_goal_mask_is_another_object(pan_pair, pair_renderer):
    other = pair_renderer.render("tomato", pair_renderer.world.object_pose("tomato"), "depth", np.random.default_rng(4))
    motion = ground(_input(pan_pair, mask1=other.mask1), FEATURES)
    assert not motion.ok and motion.reason


def test_dinov2_backend_plugs_into_ground(pan_pair, tmp_path):
    """The model backend goes through the same matching code (a tiny random model: its matches are noise, so
    the geometric hypotheses and the view check have to carry the result)."""
    from transformers import Dinov2Config, Dinov2Model

    from pipeline.perception.features import make_feature_extractor

    cfg = Dinov2Config(
        hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=64, patch_size=14, image_size=56
    )
    Dinov2Model(cfg).save_pretrained(tmp_path)
    features = make_feature_extractor("dinov2", model_id=str(tmp_path), short_side_px=112)
    motion = ground(_input(pan_pair), features, T_base_camera=pan_pair.T_base_camera)
    assert motion.ok, motion.reason
    t_err, r_err, _ = errors(pan_pair, motion)
    assert t_err < 10.0 and r_err < 4.0, (t_err, r_err)


def test_the_residual_limit_is_never_finer_than_half_the_inlier_threshold(pan_pair):
    """A relative limit shrinks with the object, sensor noise does not: a 31 mm ball's true motion fit to 1.6 mm was
    refused at 5 % of its size. With the relative limit set to nothing, the limit is half the inlier threshold."""
    from pipeline.grounding.types import GroundingConfig

    motion = ground(_input(pan_pair), FEATURES, GroundingConfig(max_registration_residual_rel=1e-6))
    assert motion.ok, motion.reason
    assert motion.residual_m <= 0.5 * motion.details["threshold_m"]


@pytest.mark.parametrize(
    ("name", "kind", "shape_kind"),
    [
        ("tomato", "ball", "ball"),
        ("bottle_a", "revolution", "revolution"),
        ("pan_a", "none", "none"),  # its handle shows every turn
        ("box_b", "box", "box"),  # its checker repeats under a half turn: the print does not tell the twins apart
    ],
)
def test_the_motion_comes_with_the_turns_its_shape_and_print_cannot_show(pair_renderer, name, kind, shape_kind):
    goal = goal_pose(pair_renderer, name, (0.06, -0.04), 40.0)
    pair = pair_renderer.render(name, goal, "depth", np.random.default_rng(1))
    motion = ground(_input(pair), FEATURES, T_base_camera=pair.T_base_camera)
    assert motion.ok, motion.reason
    assert (motion.symmetry.kind, motion.symmetry.shape_kind) == (kind, shape_kind), motion.symmetry
    assert motion.symmetry.print_unread == (name == "box_b")


def test_a_balls_motion_is_the_shift_of_its_centre(pair_renderer):
    """No turn of a ball shows, so none is reported: a turn picked up on the way would tip it in the goal depth's
    noise (raycast balls came out turned 38-129 deg) and keep it from resting along the ray (ray_rest.py)."""
    goal = goal_pose(pair_renderer, "tomato", (0.06, -0.04), 40.0)
    pair = pair_renderer.render("tomato", goal, "disparity", np.random.default_rng(1))
    motion = ground(_input(pair), FEATURES, T_base_camera=pair.T_base_camera)
    assert motion.ok and motion.symmetry.kind == "ball", (motion.reason, motion.symmetry)
    np.testing.assert_allclose(motion.R, np.eye(3), atol=1e-12)
    assert errors(pair, motion)[0] < 5.0
