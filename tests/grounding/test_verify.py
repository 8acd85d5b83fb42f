"""The view check: a motion cannot score by turning what it cannot explain away from the camera, and a right motion
that turns what was seen away keeps its evidence."""

from __future__ import annotations

import numpy as np
import open3d as o3d
from scipy.spatial.transform import Rotation

from bench.pairgen.shapes import lathe
from drivers.types import CameraIntrinsics
from pipeline.grounding.umeyama import Similarity
from pipeline.grounding.verify import chromaticity, make_view, view_consistency

K = CameraIntrinsics(160, 120, 160.0, 160.0, 79.5, 59.5)
TRAY = [(0.0, 0.0), (0.05, 0.0), (0.05, 0.03), (0.046, 0.03), (0.046, 0.004), (0.0, 0.004)]  # 10 cm across, 3 cm deep
DISC = [(0.0, 0.0), (0.05, 0.0), (0.05, 0.004), (0.0, 0.004)]  # 10 cm across, 4 mm thick


def _tray_view(up: np.ndarray, base: np.ndarray, profile=TRAY, table_at: np.ndarray | None = None):
    """A uniform body of revolution (an open tray unless `profile` says otherwise) standing at `base` on its axis
    `up` (camera frame), seen from above at a slant, on a table through `table_at` square to `up` where given:
    ray-cast depth, the body's mask and cloud."""
    R = Rotation.align_vectors([up], [[0.0, 0.0, 1.0]])[0].as_matrix()
    surfaces = [lathe(profile).triangles @ R.T + base]
    if table_at is not None:
        square = np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]], float)
        surfaces.append(square @ R.T + table_at)
    scene = o3d.t.geometry.RaycastingScene()
    for triangles in surfaces:
        vertices = triangles.reshape(-1, 3).astype(np.float32)
        scene.add_triangles(
            o3d.core.Tensor(vertices), o3d.core.Tensor(np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3))
        )
    u, v = np.meshgrid(np.arange(K.width, dtype=np.float32), np.arange(K.height, dtype=np.float32))
    rays = np.stack([0 * u, 0 * u, 0 * u, (u - K.cx) / K.fx, (v - K.cy) / K.fy, 1 + 0 * u], axis=-1)
    hits = scene.cast_rays(o3d.core.Tensor(rays.reshape(-1, 6)))
    depth = hits["t_hit"].numpy().reshape(K.height, K.width)
    mask = hits["geometry_ids"].numpy().reshape(K.height, K.width) == 0  # the body, added first
    chroma = chromaticity(np.full((K.height, K.width, 3), 128, np.uint8))
    return make_view(K.unproject_depth_image(depth)[mask], chroma[mask], depth, mask, chroma, 0.003)


def test_a_tray_turned_upside_down_does_not_explain_a_view_into_it():
    up, base = np.array([0.0, -0.6, -0.8]), np.array([0.0, 0.04, 0.5])
    view = _tray_view(up, base)
    middle = base + 0.015 * up
    ray = middle / np.linalg.norm(middle)
    across = ray - (ray @ up) * up  # the half turn about this keeps the outer wall the camera sees where it was
    H = Rotation.from_rotvec(np.pi * across / np.linalg.norm(across)).as_matrix()
    upside_down = Similarity(1.0, H, middle - H @ middle)
    still = Similarity(1.0, np.eye(3), np.zeros(3))
    assert view_consistency(still, view, view, K, 0.003).geometry > 0.99
    # its floor, turned to face away, would float in front of the floor the camera sees: 0.96 without free space
    assert view_consistency(upside_down, view, view, K, 0.003).geometry < 0.5


def test_a_disc_turned_over_is_judged_on_its_outline_too():
    """The goal camera sees a disc's other face: every point first seen faces away, so the seen points alone give
    the right motion no evidence; judged on the whole cloud, it lies inside the goal's outline just behind the face
    seen there. Slid along the table by its radius (half off the outline), pushed back by twice its size or also
    sunk under the table, it does not."""
    up, base = np.array([0.0, -0.6, -0.8]), np.array([0.0, 0.04, 0.5])
    initial, goal = _tray_view(up, base, DISC, base), _tray_view(-up, base + 0.004 * up, DISC, base)
    middle = base + 0.002 * up
    across = np.cross(up, [1.0, 0.0, 0.0])
    H = Rotation.from_rotvec(np.pi * across / np.linalg.norm(across)).as_matrix()
    over = Similarity(1.0, H, middle - H @ middle)
    right = view_consistency(over, initial, goal, K, 0.003)
    assert right.geometry < 0.05 and right.whole > 0.9
    aside = Similarity(1.0, H, over.t + np.array([0.05, 0.0, 0.0]))  # along the table: x is square to up
    assert view_consistency(aside, initial, goal, K, 0.003).whole < 0.5
    back = Similarity(1.0, H, over.t + 0.2 * middle / np.linalg.norm(middle))
    assert view_consistency(back, initial, goal, K, 0.003).whole < 0.1
    # slid half off and sunk its width under the table: what lies behind the table gives no evidence, yet at least
    # half of all points count (0.99 if only the points giving evidence did)
    under = Similarity(1.0, H, aside.t - 0.1 * up)
    assert view_consistency(under, initial, goal, K, 0.003).whole < 0.5


def test_a_models_depth_filling_a_hollow_does_not_contradict_the_right_motion():
    """A model's goal depth fills a tray's hollow from its rim: its floor floats above the measured one. Brought back
    by the right motion, the goal's floor points lie in front of the floor the capture measured, by less than the
    carve's margin: no evidence either way from a model's depth, a contradiction from a sensor's."""
    up, base = np.array([0.0, -0.6, -0.8]), np.array([0.0, 0.04, 0.5])
    capture = _tray_view(up, base)
    off = K.unproject_depth_image(np.where(capture.mask, capture.depth, 0.0)) - base
    height = off @ up
    floor = capture.mask & (height < 0.008) & (np.linalg.norm(off - height[..., None] * up, axis=-1) < 0.03)
    filled = np.where(floor, capture.depth - 0.01, capture.depth)  # 1 cm toward the camera: 2 tolerances of 5 mm
    cloud = K.unproject_depth_image(filled)[capture.mask]

    def goal(sigma_m: float):
        chroma = capture.chroma_image
        return make_view(cloud, chroma[capture.mask], filled, capture.mask, chroma, 0.003, sigma_m)

    still = Similarity(1.0, np.eye(3), np.zeros(3))
    model = view_consistency(still, capture, goal(0.002), K, 0.003).geometry
    sensor = view_consistency(still, capture, goal(0.0), K, 0.005).geometry
    assert 0.2 * capture.mask.sum() < floor.sum() < 0.5 * capture.mask.sum()
    assert model > 0.99  # 1 cm in front of the floor, on the floor's third of the tray
    assert sensor < model - 0.1
