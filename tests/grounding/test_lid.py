"""A lid's seen face measured against the table's plane: the tilt of a rendered lid, its mixed edge pixels and the
box's points beside it trimmed away, and the verdict on a close that matched its goal but left the lid open."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.types import CameraIntrinsics, RGBDFrame
from pipeline.grounding.compare import Comparison
from pipeline.grounding.lid import face_tilt_deg
from runtime.run.verification import lid_shut

K = CameraIntrinsics(320, 240, 300.0, 300.0, 160.0, 120.0)
HINGE = np.array([0.45, 0.0, 0.07])  # the lid's hinge line through here along base y, the box's top 7 cm up
LID_X_M, LID_Y_M = 0.10, 0.15


def camera_pose() -> np.ndarray:
    """T_base_camera: 0.55 m in front of the hinge line's far side and up, looking down at 50 deg."""
    down = math.radians(50.0)
    z = np.array([math.cos(down), 0.0, -math.sin(down)])  # optical axis
    x = np.array([0.0, -1.0, 0.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = HINGE + np.array([LID_X_M / 2, 0.0, 0.0]) - 0.55 * z
    return T


def render_lid(open_deg: float, edge_px: int = 3) -> tuple[RGBDFrame, np.ndarray]:
    """A depth capture of a lid open_deg from shut (turned up about HINGE), the table 7 cm below it; the lid's
    mask grown by edge_px pixels that see the table (mixed pixels at its outline)."""
    T = camera_pose()
    v, u = np.mgrid[0 : K.height, 0 : K.width]
    rays_cam = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], axis=-1)
    rays = rays_cam @ T[:3, :3].T
    origin = T[:3, 3]
    a = math.radians(open_deg)
    along, normal = np.array([math.cos(a), 0.0, math.sin(a)]), np.array([-math.sin(a), 0.0, math.cos(a)])
    s = ((HINGE - origin) @ normal) / (rays @ normal)  # ray parameter at the lid's plane
    hit = origin + s[..., None] * rays
    rel = hit - HINGE
    on_lid = (s > 0) & (rel @ along >= 0) & (rel @ along <= LID_X_M) & (np.abs(rel[..., 1]) <= LID_Y_M / 2)
    s_table = -origin[2] / rays[..., 2]
    depth = np.where(on_lid, s, s_table).astype(np.float32)  # z of a unit-z camera ray is its parameter
    import cv2

    mask = cv2.dilate(on_lid.astype(np.uint8), np.ones((2 * edge_px + 1,) * 2, np.uint8)).astype(bool)
    rgb = np.zeros((K.height, K.width, 3), np.uint8)
    return RGBDFrame(rgb, depth, K, 0.0, 0, T), mask


def base_points(frame: RGBDFrame, mask: np.ndarray) -> np.ndarray:
    T = frame.T_base_camera
    return K.unproject_depth_image(frame.depth)[mask] @ T[:3, :3].T + T[:3, 3]


@pytest.mark.parametrize("open_deg", [0.0, 6.0, 17.0, 45.0])
def test_the_faces_tilt_is_the_lids_opening_with_its_mixed_edge_pixels_trimmed(open_deg):
    frame, mask = render_lid(open_deg)
    points = base_points(frame, mask)
    a = math.radians(open_deg)
    off_lid = np.abs((points - HINGE) @ np.array([-math.sin(a), 0.0, math.cos(a)])) > 0.02
    assert 0.1 < off_lid.mean() < 0.5  # the outline's pixels see the table well below the lid
    assert face_tilt_deg(points) == pytest.approx(open_deg, abs=1.0)


def test_too_few_or_collinear_points_or_no_face_in_most_of_them_measure_no_plane():
    assert face_tilt_deg(np.zeros((10, 3))) is None
    line = np.outer(np.linspace(0, 0.1, 50), [1.0, 0.0, 0.0])
    assert face_tilt_deg(line) is None
    scatter = np.random.default_rng(1).uniform(-0.05, 0.05, (400, 3))  # no plane: a mask smeared over the scene
    assert face_tilt_deg(scatter) is None


def comparison_within_tolerance() -> Comparison:
    """What the goal comparison said of a lid left 17 deg open: 9 deg off a goal that stopped 7 deg short."""
    return Comparison(
        ok=True,
        reason="goal reached: centre within 8 mm, tilt within 8.9 deg, turn within 1.5 deg",
        position_error_m=0.008,
        rotation_error_deg=9.0,
        goal_translation_m=0.074,
        achieved_translation_m=0.069,
        goal_twist_deg=20.4,
        goal_tilt_deg=94.1,
        twist_error_deg=1.5,
        tilt_error_deg=8.9,
        twist_judged=True,
        tilt_judged=True,
        symmetry="none",
        position_tol_m=0.03,
        rotation_tol_deg=15.0,
    )


def test_a_lid_left_open_fails_verification_though_it_matched_its_goal():
    frame, mask = render_lid(17.0)
    verdict = lid_shut(frame, mask, comparison_within_tolerance(), tol_deg=10.0)
    assert not verdict.ok and "not shut" in verdict.reason
    assert verdict.lid_tilt_deg == pytest.approx(17.0, abs=1.0)


def test_a_shut_lid_is_verified():
    frame, mask = render_lid(2.0)
    verdict = lid_shut(frame, mask, comparison_within_tolerance(), tol_deg=10.0)
    assert verdict.ok and "lid shut" in verdict.reason


def test_a_lid_not_seen_is_not_verified():
    frame, mask = render_lid(0.0)
    verdict = lid_shut(frame, np.zeros_like(mask), comparison_within_tolerance(), tol_deg=10.0)
    assert not verdict.ok and "too few points" in verdict.reason


def test_a_shut_lid_off_a_goal_drawn_past_shut_is_verified_and_an_open_one_is_not():
    turned_off = comparison_within_tolerance().model_copy(
        update={"ok": False, "reason": "object tilted 21.6 deg off the goal (tolerance 15)", "tilt_error_deg": 21.6}
    )
    frame, mask = render_lid(2.0)
    verdict = lid_shut(frame, mask, turned_off, tol_deg=10.0)
    assert verdict.ok and "lid shut within" in verdict.reason and "21.6 deg off the goal" in verdict.reason
    frame, mask = render_lid(25.0)
    assert not lid_shut(frame, mask, turned_off, tol_deg=10.0).ok


def _box_points() -> np.ndarray:
    """The box under the lid: its top and sides, 7 cm tall, the hinge along its far top edge (x = 0.45)."""
    x, y, z = np.meshgrid(np.linspace(0.45, 0.55, 21), np.linspace(-0.075, 0.075, 31), np.linspace(0.0, 0.07, 15))
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def test_a_shut_lid_lies_over_its_box_and_an_open_or_fallen_one_does_not():
    from pipeline.grounding.lid import over_its_box

    box = _box_points()
    for open_deg, over in ((0.0, True), (4.0, True), (60.0, False), (90.0, False)):
        frame, mask = render_lid(open_deg)
        assert over_its_box(base_points(frame, mask), box) is over, open_deg
    frame, mask = render_lid(0.0)
    fallen = base_points(frame, mask) + np.array([0.0, 0.2, -0.07])  # beside the box, on the table
    assert not over_its_box(fallen, box)
    assert not over_its_box(base_points(frame, mask), box[:10])  # too few of the box's points to tell


def test_a_shut_lid_whose_motion_could_not_be_measured_is_judged_by_its_face():
    unmeasured = "could not measure the achieved motion: no turn about the hinge explains the images"
    frame, mask = render_lid(1.0)
    verdict = lid_shut(frame, mask, None, tol_deg=10.0, unmeasured=unmeasured)
    assert verdict.ok and verdict.comparison is None
    assert "over its box" in verdict.reason and unmeasured in verdict.reason
    frame, mask = render_lid(30.0)
    assert not lid_shut(frame, mask, None, tol_deg=10.0, unmeasured=unmeasured).ok
