"""Hinged parts: the hinge from where a part meets its anchor, and the turn about it recovered from the images."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.articulation import HingeNotFound, find_hinge
from pipeline.grounding.ground import ground
from pipeline.grounding.sim_pairs import _relative_prediction
from pipeline.grounding.types import GroundingInput
from pipeline.perception.features import make_feature_extractor


def plate(width: float, height: float, step: float = 0.004) -> np.ndarray:
    """Points of an upright plate in the x = 0 plane, bottom edge on z = 0, spanning y in [-width/2, width/2]."""
    y, z = np.meshgrid(np.arange(-width / 2, width / 2, step), np.arange(0.0, height, step))
    return np.column_stack([np.zeros(y.size), y.ravel(), z.ravel()])


def test_hinge_is_the_edge_where_the_part_meets_its_anchor():
    lid = plate(0.16, 0.12)
    wall_top = np.column_stack([np.zeros(60), np.linspace(-0.08, 0.08, 60), np.full(60, -0.004)])
    hinge = find_hinge(lid, wall_top)
    assert abs(abs(hinge.axis[1]) - 1.0) < 1e-3  # along the wall
    assert abs(hinge.point[2]) < 0.003 and abs(hinge.point[0]) < 1e-6  # at the lid's bottom edge, not mid-band
    shut = hinge.turn(np.radians(90.0) * np.sign(hinge.axis[1])).apply(lid)  # right-handed about +y: z -> x
    assert np.allclose(shut[:, 2], 0.0, atol=1e-9) and shut[:, 0].max() > 0.11


def test_no_hinge_when_the_part_does_not_meet_its_anchor_along_a_line():
    lid = plate(0.16, 0.12)
    far = np.array([[0.3, 0.0, 0.0], [0.3, 0.01, 0.0]])
    with pytest.raises(HingeNotFound, match="does not meet its anchor"):
        find_hinge(lid, far)
    corner = np.array([[0.0, 0.08, -0.003]])  # the anchor touches the lid at one corner only
    with pytest.raises(HingeNotFound, match="is no line"):
        find_hinge(plate(0.16, 0.12, step=0.002), corner)
    with pytest.raises(HingeNotFound, match="no 3D points"):
        find_hinge(lid, np.empty((0, 3)))


def test_lid_turn_is_recovered_from_the_rendered_views(lid_views):
    open_frame, shut_frame, lid_open, lid_shut, box_open, T_true = lid_views
    rng = np.random.default_rng(0)
    inp = GroundingInput(
        open_frame.rgb,
        open_frame.depth,
        lid_open,
        shut_frame.rgb,
        _relative_prediction(shut_frame.depth, "disparity", rng, 0.002),
        "disparity",
        lid_shut,
        open_frame.intrinsics,
        anchor0=box_open,
    )
    motion = ground(inp, make_feature_extractor("offline"), T_base_camera=open_frame.T_base_camera)
    assert motion.ok, motion.reason
    points = open_frame.intrinsics.unproject_depth_image(open_frame.depth)[lid_open & np.isfinite(open_frame.depth)]
    centre = points.mean(axis=0)
    error_m = np.linalg.norm(motion.R @ centre + motion.t - (T_true[:3, :3] @ centre + T_true[:3, 3]))
    error_deg = np.degrees(Rotation.from_matrix(motion.R @ T_true[:3, :3].T).magnitude())
    assert error_m < 0.005 and error_deg < 3.0, f"{error_m * 1000:.1f} mm, {error_deg:.1f} deg"
    assert abs(abs(motion.details["hinge_angle_deg"]) - 99.5) < 3.0


def test_hinged_target_without_a_hinge_is_refused(lid_views):
    open_frame, shut_frame, lid_open, lid_shut, box_open, _ = lid_views
    far_away = np.zeros_like(box_open)
    far_away[-40:-30, 20:60] = True  # table pixels, nowhere near the lid
    inp = GroundingInput(
        open_frame.rgb,
        open_frame.depth,
        lid_open,
        shut_frame.rgb,
        1.0 / shut_frame.depth,
        "disparity",
        lid_shut,
        open_frame.intrinsics,
        anchor0=far_away,
    )
    motion = ground(inp, make_feature_extractor("offline"))
    assert not motion.ok and "hinged target: the part does not meet its anchor" in motion.reason
