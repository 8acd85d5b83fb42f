"""Verification's measurement of the achieved motion (measure_achieved) on a plain box turned on the table: the
expected motion, handed over as a hint, keeps the registration off a tipped twin that keeps the first-seen faces in
view, and still lets a box that did not turn, or turned too far, be judged so."""

from __future__ import annotations

import numpy as np
import pytest
from grounding_helpers import goal_pose
from scipy.spatial.transform import Rotation

from drivers.types import RGBDFrame
from pipeline.grounding.achieved import measure_achieved
from pipeline.grounding.compare import Comparison, compare
from pipeline.perception.offline_features import OfflineFeatures

SCENE = """name: plain_box
description: one plain box, sides of three lengths, lying on its largest face
objects:
  - {name: block, kind: box, size_m: [0.046, 0.054, 0.031], color: pink, xy_m: [0.50, 0.05], jitter: false}
"""


@pytest.fixture(scope="module")
def box_world(sim_profile_with, tmp_path_factory):
    from drivers.sim import SimWorld
    from pipeline.grounding.sim_pairs import PairRenderer

    path = tmp_path_factory.mktemp("scene") / "plain_box.yaml"
    path.write_text(SCENE)
    profile = sim_profile_with({"sim": {"scene": str(path)}})
    renderer = PairRenderer(SimWorld(profile.sim, profile.camera))
    yield renderer, profile.pipeline.grounding
    renderer.close()


def turn_about_centre_camera(renderer, deg: float) -> np.ndarray:
    """The camera-frame motion of turning the block by `deg` about the vertical through its centre."""
    c = renderer._centre("block")
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("z", deg, degrees=True).as_matrix()
    T[:3, 3] = c - T[:3, :3] @ c
    return np.linalg.inv(renderer.T_base_camera) @ T @ renderer.T_base_camera


def judge_turn(box_world, turned_deg: float, goal_deg: float) -> Comparison:
    """The block really turned by turned_deg; the goal asked for goal_deg; the verdict as verification gives it."""
    renderer, cfg = box_world
    pair = renderer.render("block", goal_pose(renderer, "block", (0.0, 0.0), turned_deg), "depth",
                           np.random.default_rng(0), pred_noise_rel=0.0)  # fmt: skip
    goal = turn_about_centre_camera(renderer, goal_deg)
    achieved = measure_achieved(
        before=RGBDFrame(pair.rgb0, pair.depth0, pair.intrinsics, 0.0, 0, pair.T_base_camera),
        mask_before=pair.mask0,
        after=RGBDFrame(pair.rgb1, pair.depth1.astype(np.float32), pair.intrinsics, 0.0, 1, pair.T_base_camera),
        mask_after=pair.mask1,
        anchor_before=None,
        features=OfflineFeatures(),
        config=cfg,
        expected=(goal[:3, :3], goal[:3, 3]),
    )
    assert achieved.ok, achieved.reason
    return compare(
        goal_R=goal[:3, :3],
        goal_t=goal[:3, 3],
        achieved_R=achieved.R,
        achieved_t=achieved.t,
        centre_camera=achieved.centre_camera,
        R_base_camera=pair.T_base_camera[:3, :3],
        position_tol_m=0.03,
        rotation_tol_deg=15.0,
        symmetry=achieved.symmetry,
    )


def test_a_turn_short_of_the_goal_is_measured_as_it_is(box_world):
    verdict = judge_turn(box_world, 76.0, 90.0)
    assert verdict.ok and verdict.twist_error_deg == pytest.approx(14.0, abs=2.5), verdict.reason
    assert verdict.tilt_error_deg < 5.0  # not a twin tipped onto another face


def test_a_half_turn_no_view_shows_is_not_held_against_the_run(box_world):
    verdict = judge_turn(box_world, -90.0, 90.0)  # 180 deg from the goal: a plain box looks the same
    assert verdict.ok and verdict.twist_error_deg < 5.0, verdict.reason


@pytest.mark.parametrize(("turned", "error"), [(0.0, 90.0), (60.0, 30.0), (180.0, 90.0)])
def test_a_box_that_did_not_reach_its_turn_still_fails(box_world, turned, error):
    verdict = judge_turn(box_world, turned, 90.0)
    assert not verdict.ok and verdict.twist_error_deg == pytest.approx(error, abs=3.0), verdict.reason


def test_a_body_of_revolution_is_hinted_spun_about_its_own_axis():
    """A bottle stood up: the goal's spin about the bottle's axis is arbitrary and decides which side faces the
    camera, so the hints spin it all round; each moves the axis where the goal does."""
    from pipeline.grounding.achieved import HINT_SPIN_STEP_DEG, expected_hints
    from pipeline.grounding.compare import Symmetry

    centre, axis = np.array([0.0, 0.1, 0.8]), np.array([1.0, 0.0, 0.0])
    R = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    t = np.array([0.05, 0.0, 0.0])
    hints = expected_hints(R, t, centre, np.array([0.0, -1.0, 0.0]), Symmetry(centre, axis))
    assert len(hints) == round(360 / HINT_SPIN_STEP_DEG)
    on_axis = centre + np.outer([-0.05, 0.05], axis)
    spins = []
    for h in hints:
        np.testing.assert_allclose(h.apply(on_axis), on_axis @ R.T + t, atol=1e-9)
        spins.append(Rotation.from_matrix(R.T @ h.R).magnitude())
    assert np.degrees(max(spins)) == pytest.approx(180.0)  # all the way round
