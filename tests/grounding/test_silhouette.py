"""Where a goal lies across the camera ray, from its outline: a ball's centre on the ray through the outline's
centre, a body of revolution's axis in the plane the outline is symmetric about; along the ray, on its support."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from grounding_helpers import grounded_raycast

from drivers.types import CameraIntrinsics
from pipeline.grounding.ray_rest import ball_surface
from pipeline.grounding.silhouette import (
    axis_into_plane,
    axis_turned_to_outline,
    mirror_plane,
    onto_ray,
    silhouette_ray,
)
from pipeline.grounding.umeyama import Similarity

K = CameraIntrinsics(width=640, height=480, fx=600.0, fy=600.0, cx=319.5, cy=239.5)
CENTRE = np.array([0.15, 0.08, 0.9])  # off the optical axis: its silhouette is an ellipse, not a circle
RADIUS = 0.03


def _silhouette(centre: np.ndarray = CENTRE, radius: float = RADIUS) -> np.ndarray:
    """The pixels whose ray passes within `radius` of `centre`."""
    u, v = np.meshgrid(np.arange(K.width), np.arange(K.height))
    rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones(u.shape)], axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    along = rays @ centre
    return np.linalg.norm(rays * along[..., None] - centre, axis=-1) < radius


def _miss_m(ray: np.ndarray, point: np.ndarray = CENTRE) -> float:
    """How far the ray passes from the point [m]."""
    return float(np.linalg.norm(point - ray * (point @ ray)))


def test_the_ray_through_a_balls_silhouette_passes_through_its_centre_whatever_the_segmenters_errors():
    mask = _silhouette()
    assert _miss_m(silhouette_ray(mask, K)) < 0.0005  # a third of a pixel at 0.9 m
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)  # 3 px too wide
    assert _miss_m(silhouette_ray(grown, K)) < 0.0005
    holed = mask.copy()
    ys, xs = np.nonzero(mask)
    holed[ys[::7], xs[::7]] = False  # the segmenter's holes
    assert _miss_m(silhouette_ray(holed, K)) < 0.0005


def test_a_silhouette_cut_by_the_images_edge_or_partly_hidden_gives_no_ray():
    at_edge = _silhouette(np.array([0.47, 0.0, 0.9]))  # its right part beyond the image
    assert at_edge[:, -1].any() and silhouette_ray(at_edge, K) is None
    hidden = _silhouette()
    columns = np.nonzero(hidden.any(axis=0))[0]
    hidden[:, : int(np.median(columns))] = False  # half of it behind something
    assert silhouette_ray(hidden, K) is None
    assert silhouette_ray(np.zeros((K.height, K.width), bool), K) is None


def test_onto_the_ray_keeps_the_centres_distance_and_turn():
    ray = np.array([0.1, -0.05, 1.0]) / np.linalg.norm([0.1, -0.05, 1.0])
    aside = Similarity(1.0, np.eye(3), np.array([0.02, 0.01, 0.0]))
    moved = onto_ray(aside, CENTRE, ray)
    goal = moved.apply(CENTRE[None])[0]
    assert _miss_m(ray, goal) < 1e-9
    assert abs(np.linalg.norm(goal) - np.linalg.norm(aside.apply(CENTRE[None])[0])) < 0.001
    assert np.array_equal(moved.R, aside.R)


CAMERA_W = np.array([0.0, -0.6, 0.7])  # world frame: z up, the camera 0.7 m above the table looking down at it


def _world_to_camera() -> np.ndarray:
    forward = np.array([0.0, 0.1, 0.0]) - CAMERA_W
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    return np.stack([right, np.cross(forward, right), forward])  # rows: the camera's x (right), y (down), z


def _standing_can(base_w: np.ndarray, handle: bool = False) -> np.ndarray:
    """The outline (mask) of a can standing on the table at `base_w`, 35 mm in radius, 100 mm tall; with `handle`,
    a mug's handle out to one side."""
    turn, height = np.meshgrid(np.linspace(0, 2 * np.pi, 720), np.linspace(0, 0.1, 200))
    side = np.stack([0.035 * np.cos(turn), 0.035 * np.sin(turn), height], axis=-1).reshape(-1, 3)
    radius = np.linspace(0, 0.035, 60)[:, None] * np.ones(720)
    turns = np.linspace(0, 2 * np.pi, 720)
    top = np.stack([radius * np.cos(turns), radius * np.sin(turns), np.full(radius.shape, 0.1)], -1).reshape(-1, 3)
    parts = [side, top]
    if handle:
        out, up = np.meshgrid(np.linspace(0.035, 0.065, 40), np.linspace(0.02, 0.08, 80))
        parts.append(np.stack([out.ravel(), np.zeros(out.size), up.ravel()], axis=1))
    points = (np.vstack(parts) + base_w - CAMERA_W) @ _world_to_camera().T
    u = np.round(K.fx * points[:, 0] / points[:, 2] + K.cx).astype(int)
    v = np.round(K.fy * points[:, 1] / points[:, 2] + K.cy).astype(int)
    mask = np.zeros((K.height, K.width), np.uint8)
    mask[v, u] = 1
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)).astype(bool)


@pytest.mark.parametrize("base_w", [(0.12, 0.1, 0.0), (-0.2, 0.25, 0.0)])
def test_a_standing_body_of_revolutions_outline_is_symmetric_about_the_plane_through_its_axis(base_w):
    base_w = np.asarray(base_w)
    up = _world_to_camera() @ [0.0, 0.0, 1.0]
    axis_point = _world_to_camera() @ (base_w - CAMERA_W)
    mask = _standing_can(base_w)
    normal = mirror_plane(mask, K, up)
    assert abs(normal @ up) < 1e-9 and abs(axis_point @ normal) < 0.0005
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    assert abs(axis_point @ mirror_plane(grown, K, up)) < 0.0005
    aside = Similarity(1.0, np.eye(3), 0.01 * normal + 0.004 * up)  # 10 mm to one side of where the image shows it
    moved = axis_into_plane(aside, axis_point, up, mask, K).apply(axis_point[None])[0]
    assert abs(moved @ normal) < 0.0005 and abs((moved - axis_point) @ up - 0.004) < 1e-9  # sideways only


def _lying_can(centre_w: np.ndarray, axis_w: np.ndarray) -> np.ndarray:
    """The outline (mask) of a can lying on its side on the table, 35 mm in radius and 120 mm long, its middle at
    `centre_w` and its axis along `axis_w` (world frame)."""
    a = axis_w / np.linalg.norm(axis_w)
    e1 = np.cross(a, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    turn, along = np.meshgrid(np.linspace(0, 2 * np.pi, 720), np.linspace(-0.06, 0.06, 240))
    side = np.outer(along.ravel(), a) + 0.035 * (
        np.outer(np.cos(turn.ravel()), e1) + np.outer(np.sin(turn.ravel()), e2)
    )
    r, t = np.meshgrid(np.linspace(0, 0.035, 60), np.linspace(0, 2 * np.pi, 720))
    disc = np.outer(r.ravel() * np.cos(t.ravel()), e1) + np.outer(r.ravel() * np.sin(t.ravel()), e2)
    points = (np.vstack([side, disc + 0.06 * a, disc - 0.06 * a]) + centre_w - CAMERA_W) @ _world_to_camera().T
    u = np.round(K.fx * points[:, 0] / points[:, 2] + K.cx).astype(int)
    v = np.round(K.fy * points[:, 1] / points[:, 2] + K.cy).astype(int)
    mask = np.zeros((K.height, K.width), np.uint8)
    mask[v, u] = 1
    return cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8)).astype(bool)


@pytest.mark.parametrize("off_deg", [6.0, -12.0])
def test_a_tipped_bodys_axis_is_turned_across_the_ray_to_where_its_outline_is_symmetric(off_deg):
    """A can lying on its side whose motion turns its axis about the goal ray: the outline's symmetry turns it
    back (grown mask too); a right motion is kept as it is."""
    from scipy.spatial.transform import Rotation

    centre_w, axis_w = np.array([0.05, 0.15, 0.035]), np.array([np.cos(0.5), np.sin(0.5), 0.0])
    centre, axis = _world_to_camera() @ (centre_w - CAMERA_W), _world_to_camera() @ axis_w
    mask = _lying_can(centre_w, axis_w)
    truth = Similarity(1.0, np.eye(3), np.zeros(3))  # the goal as the start, for simplicity
    turn = Rotation.from_rotvec(np.radians(off_deg) * centre / np.linalg.norm(centre)).as_matrix()
    off = Similarity(1.0, turn, centre - turn @ centre)
    grown = cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    for outline in (mask, grown):
        back = axis_turned_to_outline(off, centre, axis, outline, K)
        assert np.degrees(np.arccos(min(1.0, (back.R @ axis) @ axis))) < 0.7
        np.testing.assert_allclose(back.apply(centre[None])[0], centre, atol=1e-9)  # turned about its goal ray
    assert axis_turned_to_outline(truth, centre, axis, mask, K) is truth


def test_an_outline_with_a_handle_or_partly_hidden_gives_no_plane():
    up = _world_to_camera() @ [0.0, 0.0, 1.0]
    assert mirror_plane(_standing_can(np.array([0.12, 0.1, 0.0]), handle=True), K, up) is None
    hidden = _standing_can(np.array([-0.2, 0.25, 0.0]))
    rows, columns = np.nonzero(hidden.any(axis=1))[0], np.nonzero(hidden.any(axis=0))[0]
    hidden[int(np.median(rows)) :, : int(np.median(columns))] = False  # its lower left behind something
    assert mirror_plane(hidden, K, up) is None


def test_a_balls_surface_is_covered_evenly():
    points = ball_surface(CENTRE, RADIUS)
    assert np.allclose(np.linalg.norm(points - CENTRE, axis=1), RADIUS)
    assert np.linalg.norm(points.mean(axis=0) - CENTRE) < 0.001
    assert np.ptp(points[:, 2]) > 1.98 * RADIUS  # from its bottom to its top


@pytest.mark.parametrize(
    "seed, index, kind, within_mm",
    [(31, 15, "ball", 3.0), (9001, 23, "ball", 3.0), (9001, 28, "bowl", 2.5)],
)
def test_a_round_body_slid_across_the_table_lands_where_its_outline_and_its_support_put_it(
    seed, index, kind, within_mm
):
    """Raycast pairs (a model's goal depth, flattened and warped under the object) whose answers were 35, 9 and
    4.8 mm off, most of it across the ray: ICP and the sphere fit followed the goal depth, not the image."""
    from bench.pairgen.scoring import translation_error_mm

    p, motion = grounded_raycast(seed, index)
    assert p.object_kind == kind
    assert translation_error_mm(motion.R, motion.t, p.T_motion_camera, p.centre_camera) < within_mm


@pytest.mark.parametrize("off_mm, accepted", [(45.0, True), (150.0, False)])
def test_the_checks_judge_the_registration_and_an_outline_far_off_it_refuses(monkeypatch, off_mm, accepted):
    """A ball's goal is put on its outline's ray after the registration's checks, which judge the fit to the goal
    cloud that the move corrects: checked after it, this ball (registered 20 mm across the ray from the truth) with
    its outline's ray 45 mm aside kept 19 of its 430 points within the inlier threshold and was refused. An outline
    further off than the object's size (75 mm) is no depth error, and refuses. Raycast 31:15 with the outline's ray
    turned `off_mm` aside at the ball."""
    import pipeline.grounding.ground as ground_module
    from bench.pairgen.generate import make_pair
    from pipeline.grounding.types import GroundingConfig, GroundingInput
    from pipeline.perception.offline_features import OfflineFeatures

    p = make_pair(31, 15)
    truth = p.T_motion_camera[:3, :3] @ p.centre_camera + p.T_motion_camera[:3, 3]
    side = np.cross(truth, [0.0, 1.0, 0.0])
    aside = truth + off_mm / 1000 * side / np.linalg.norm(side)
    monkeypatch.setattr(ground_module, "silhouette_ray", lambda mask, K: aside / np.linalg.norm(aside))
    inp = GroundingInput(p.rgb0, p.depth0, p.mask0, p.rgb1, p.depth1, p.depth1_kind, p.mask1, p.intrinsics)
    motion = ground_module.ground(inp, OfflineFeatures(), GroundingConfig(), T_base_camera=p.T_base_camera)
    assert motion.ok == accepted, motion.reason
    if accepted:  # on the outline's ray, and the move recorded
        centre = motion.R @ p.centre_camera + motion.t
        ray = aside / np.linalg.norm(aside)
        assert np.linalg.norm(centre - (centre @ ray) * ray) < 0.003
        assert motion.details["moved_across_ray_m"] > 0.005
    else:
        assert "across the camera ray" in motion.reason


def test_a_right_motion_is_not_turned_where_the_start_axis_is_read_off():
    """Raycast 1357:17: a can lying across the view, its start axis read some degrees off: its goal outline is most
    symmetric about that axis turned 9 deg from the right motion, which the views show worse (agreement 0.82 ->
    0.36): the motion is kept."""
    from bench.pairgen.scoring import rotation_error_deg

    p, motion = grounded_raycast(1357, 17)
    assert (p.object_kind, p.motion_kind) == ("cylinder", "tip")
    T, R0 = p.T_motion_camera, p.T_camera_object0[:3, :3]
    assert rotation_error_deg(motion.R, T[:3, :3], R0, p.shape_symmetry) < 2.0
