"""Point-cloud obstacle from a simulated Femto Bolt frame: the robot's own points and the target are removed."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.sim import SimCamera, SimWorld
from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.geometry import transform_points
from safety.pointcloud import cloud_from_frame, voxel_downsample


@pytest.fixture(scope="module")
def scene(sim_profile_with):
    profile = sim_profile_with()
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=1) as camera:
        frame = camera.read().with_extrinsics(camera.T_base_camera)
        masks = camera.object_masks()
    return world, frame, masks


def _raw_points(frame) -> np.ndarray:
    pts = frame.intrinsics.unproject_depth_image(frame.depth)[np.isfinite(frame.depth)]
    pts = transform_points(frame.T_base_camera, pts)
    return voxel_downsample(pts[pts[:, 2] > 0.01], 0.01)


def _near(points: np.ndarray, center: np.ndarray, radius: float) -> int:
    return int(np.sum(np.linalg.norm(points[:, :2] - center[:2], axis=1) < radius))


def test_robot_sees_itself_unless_its_points_are_removed(robot, scene):
    _, frame, _ = scene
    raw = _raw_points(frame)
    assert CollisionWorld(robot, points=raw).in_collision(robot.home_q)  # the arm's own image
    cloud = cloud_from_frame(frame, robot, robot.home_q)
    assert 100 < len(cloud) < len(raw)
    assert not CollisionWorld(robot, points=cloud).in_collision(robot.home_q)


def test_target_mask_removes_the_object(robot, scene):
    world, frame, masks = scene
    center = world.object_pose("red_block")[:3, 3]
    kept = cloud_from_frame(frame, robot, robot.home_q)
    assert _near(kept, center, 0.02) > 5  # the block is an obstacle ...
    cleared = cloud_from_frame(frame, robot, robot.home_q, exclude_mask=masks["red_block"])
    assert _near(cleared, center, 0.03) == 0  # ... unless it is the target
    other = world.object_pose("blue_block")[:3, 3]
    assert _near(cleared, other, 0.02) > 5  # other objects stay


def test_crop_and_table_are_applied(robot, scene):
    _, frame, _ = scene
    ws = SafetyConfig().workspace
    cloud = cloud_from_frame(frame, robot, robot.home_q, crop=ws)
    assert np.all(cloud >= np.asarray(ws.min_m) - 1e-9) and np.all(cloud <= np.asarray(ws.max_m) + 1e-9)
    assert cloud[:, 2].min() > 0.01 - 0.005  # voxel centroids of points above the table clearance


def test_frame_without_extrinsics_is_refused(robot, scene):
    _, frame, _ = scene
    from dataclasses import replace

    with pytest.raises(ValueError, match="T_base_camera"):
        cloud_from_frame(replace(frame, T_base_camera=None), robot, robot.home_q)
