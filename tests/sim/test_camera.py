"""The simulated Femto Bolt: geometry of the rendered depth, the noise model and invalid pixels."""

import numpy as np
import pytest

from drivers.sim import SimCamera, SimWorld
from drivers.sim.gl import mujoco
from drivers.sim.world import CAMERA_NAME


@pytest.fixture(scope="module")
def world_and_frame(sim_profile_with):
    profile = sim_profile_with()
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=3) as camera:
        frame = camera.read()
        masks = camera.object_masks()
        T = camera.T_base_camera
    return world, frame, masks, T


def table_pixels(world, frame):
    """Pixels whose first hit is the table top, from the renderer's own segmentation."""
    r = mujoco.Renderer(world.model, frame.intrinsics.height, frame.intrinsics.width)
    try:
        r.enable_segmentation_rendering()
        r.update_scene(world.data, CAMERA_NAME)
        seg = r.render()
    finally:
        r.close()
    return (seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM)) & (seg[..., 0] == world.model.geom("table").id)


def test_table_depth_matches_the_analytic_plane_within_the_noise_model(world_and_frame):
    world, frame, _, T = world_and_frame
    K = frame.intrinsics
    v, u = np.mgrid[0 : K.height, 0 : K.width]
    rays = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], -1)  # z = 1
    # plane z_base = 0: z_base(depth) = T[2,3] + depth * (R[2] . ray) = 0
    denom = rays @ T[2, :3]
    analytic = -T[2, 3] / denom
    table = table_pixels(world, frame) & np.isfinite(frame.depth)
    table[:2, :] = table[-2:, :] = False
    assert table.sum() > 0.4 * table.size
    residual = (frame.depth - analytic)[table]
    sigma = world.camera_config.sim.depth_noise_sigma_m * analytic[table]
    z = residual / sigma
    assert abs(np.mean(z)) < 0.05  # unbiased
    assert 0.9 < np.std(z) < 1.1  # noise as modelled
    assert np.mean(np.abs(z) < 4) > 0.999


def test_invalid_pixels_at_silhouettes_and_out_of_range(world_and_frame):
    _, frame, masks, _ = world_and_frame
    block = masks["red_block"]
    assert block.sum() > 100
    dilated = block.copy()
    dilated[1:] |= block[:-1]
    dilated[:-1] |= block[1:]
    dilated[:, 1:] |= block[:, :-1]
    dilated[:, :-1] |= block[:, 1:]
    border = dilated & ~block
    assert np.isnan(frame.depth[border]).mean() > 0.3  # flying pixels are dropped at the block's edge
    interior = block.copy()
    for axis, shift in ((0, 1), (0, -1), (1, 1), (1, -1)):
        interior &= np.roll(block, shift, axis)
    assert np.isfinite(frame.depth[interior]).mean() > 0.95
    valid = frame.depth[np.isfinite(frame.depth)]
    assert valid.min() >= 0.5 and valid.max() <= 3.86


def test_max_range_marks_far_pixels_invalid(sim_profile_with):
    profile = sim_profile_with({"camera": {"max_depth_m": 1.0}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world) as camera:
        depth = camera.read().depth
    assert np.nanmax(depth) <= 1.0
    assert np.isnan(depth[:10]).mean() > 0.8  # the top rows look far across the table (the robot is nearer)


def test_frames_are_sequential_and_drops_and_timeouts_are_injected(sim_profile_with):
    from drivers.errors import CameraTimeoutError

    faults = {"camera_drop_every_n": 2, "camera_timeout_after_s": 0.5}
    profile = sim_profile_with({"sim": {"faults": faults}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world) as camera:
        stamps = []
        for _ in range(3):
            stamps.append(camera.read(timeout_s=0.1).stamp_s)
            world.step(0.04)
        assert stamps == sorted(stamps) and len(set(stamps)) == 3
        world.step(0.5)
        with pytest.raises(CameraTimeoutError):
            camera.read(timeout_s=0.05)
