"""Simulated Femto Bolt: colour + depth aligned to colour, rendered from the MuJoCo world.

Depth behaves like the real sensor's: range-dependent noise, invalid (NaN) pixels outside the working range and
at depth discontinuities (ToF flying pixels), a frame period of 1/fps, and fault hooks (dropped frames, a camera
that stops delivering).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from drivers.errors import CameraTimeoutError, NotConnectedError
from drivers.interfaces import Camera
from drivers.sim.gl import mujoco
from drivers.sim.world import CAMERA_NAME, SimWorld
from drivers.types import CameraIntrinsics, RGBDFrame


def sim_intrinsics(world: SimWorld) -> CameraIntrinsics:
    """Pinhole intrinsics of the MuJoCo camera (square pixels, principal point at the image centre)."""
    c = world.camera_config
    fovy = math.radians(world.model.cam(CAMERA_NAME).fovy[0])
    f = (c.height_px / 2) / math.tan(fovy / 2)
    return CameraIntrinsics(c.width_px, c.height_px, f, f, c.width_px / 2 - 0.5, c.height_px / 2 - 0.5)


def invalidate_depth_edges(depth: np.ndarray, jump_m: float) -> np.ndarray:
    """NaN where a 4-neighbour differs by more than jump_m (mixed pixels at object silhouettes)."""
    out = depth.copy()
    edge = np.zeros(depth.shape, dtype=bool)
    dv = np.abs(np.diff(depth, axis=0)) > jump_m
    dh = np.abs(np.diff(depth, axis=1)) > jump_m
    edge[1:, :] |= dv
    edge[:-1, :] |= dv
    edge[:, 1:] |= dh
    edge[:, :-1] |= dh
    out[edge] = np.nan
    return out


class SimCamera(Camera):
    def __init__(self, world: SimWorld, seed: int = 0) -> None:
        self.world = world
        self.config = world.camera_config
        self._intrinsics = sim_intrinsics(world)
        self._rng = np.random.default_rng(seed)
        self._render_lock = threading.Lock()
        self._renderer: mujoco.Renderer | None = None
        self._render_data = mujoco.MjData(world.model)
        self._frame_id = 0
        self._last_stamp = -math.inf
        self._reads = 0

    @property
    def intrinsics(self) -> CameraIntrinsics:
        return self._intrinsics

    @property
    def is_connected(self) -> bool:
        return self._renderer is not None

    @property
    def T_base_camera(self) -> np.ndarray:
        """Ground-truth extrinsics (the base frame is the world frame)."""
        return self.world.camera_pose()

    def connect(self) -> None:
        if self._renderer is None:
            self._renderer = mujoco.Renderer(self.world.model, self.config.height_px, self.config.width_px)

    def close(self) -> None:
        with self._render_lock:
            if self._renderer is not None:
                self._renderer.close()
                self._renderer = None

    def _snapshot(self) -> float:
        """Copy the world state into the render data (briefly under the world lock); returns its time."""
        w = self.world
        with w.lock:
            self._render_data.qpos[:] = w.data.qpos
            self._render_data.time = w.data.time
        mujoco.mj_kinematics(w.model, self._render_data)
        mujoco.mj_camlight(w.model, self._render_data)
        return float(self._render_data.time)

    def _wait_for_next_frame(self, timeout_s: float) -> float:
        """Wait until a frame period has passed since the last frame (in sim time); returns the frame time."""
        faults = self.world.config.faults
        period = 1.0 / self.config.fps
        deadline = time.monotonic() + timeout_s
        while True:
            now = self.world.time
            stopped = faults.camera_timeout_after_s is not None and now >= faults.camera_timeout_after_s
            if not stopped and now >= self._last_stamp + period:
                return now
            if time.monotonic() >= deadline:
                raise CameraTimeoutError(f"sim camera: no new frame within {timeout_s:.2f} s")
            if self.world._thread is None:  # stepped world: time only moves when the caller steps it
                if stopped:
                    raise CameraTimeoutError(f"sim camera: no new frame within {timeout_s:.2f} s")
                return now
            time.sleep(0.002)

    def read(self, timeout_s: float | None = None) -> RGBDFrame:
        if self._renderer is None:
            raise NotConnectedError("SimCamera.read() before connect()")
        timeout_s = self.config.read_timeout_s if timeout_s is None else timeout_s
        drop_n = self.world.config.faults.camera_drop_every_n
        with self._render_lock:
            self._wait_for_next_frame(timeout_s)
            self._reads += 1
            if drop_n and self._reads % drop_n == 0:  # the dropped frame is skipped: wait for the next one
                self._last_stamp = self.world.time
                self._wait_for_next_frame(timeout_s)
            stamp = self._snapshot()
            r = self._renderer
            r.update_scene(self._render_data, CAMERA_NAME)
            rgb = r.render().copy()
            r.enable_depth_rendering()
            r.update_scene(self._render_data, CAMERA_NAME)
            depth = r.render().astype(np.float32)
            r.disable_depth_rendering()
            self._last_stamp = stamp
            self._frame_id += 1
            return RGBDFrame(rgb, self._sensor_depth(depth), self._intrinsics, stamp, self._frame_id)

    def object_masks(self) -> dict[str, np.ndarray]:
        """Ground-truth visibility masks (H, W bool) of every scene object in the last frame read."""
        m = self.world.model
        root_of_geom = np.append(m.body_rootid[m.geom_bodyid], -1)  # index -1 -> -1 (no geom)
        roots = root_of_geom[self._geom_ids("object_masks")]
        return {o.name: roots == m.body(o.name).id for o in self.world.scene.objects}

    def body_mask(self, body: str) -> np.ndarray:
        """Ground-truth visibility mask of one body alone, e.g. an object's part ("box_lid")."""
        m = self.world.model
        body_of_geom = np.append(m.geom_bodyid, -1)
        return body_of_geom[self._geom_ids("body_mask")] == m.body(body).id

    def _geom_ids(self, what: str) -> np.ndarray:
        """The geom seen at each pixel (-1: none), from a segmentation render of the current state."""
        if self._renderer is None:
            raise NotConnectedError(f"SimCamera.{what}() before connect()")
        with self._render_lock:
            r = self._renderer
            r.enable_segmentation_rendering()
            r.update_scene(self._render_data, CAMERA_NAME)
            seg = r.render()
            r.disable_segmentation_rendering()
        return np.where(seg[..., 1] == int(mujoco.mjtObj.mjOBJ_GEOM), seg[..., 0], -1)

    def _sensor_depth(self, depth: np.ndarray) -> np.ndarray:
        c = self.config
        noisy = depth + self._rng.normal(0.0, 1.0, depth.shape).astype(np.float32) * (c.sim.depth_noise_sigma_m * depth)
        noisy = invalidate_depth_edges(noisy, c.sim.edge_invalid_jump_m)
        noisy[~((noisy >= c.min_depth_m) & (noisy <= c.max_depth_m))] = np.nan  # range gate on the measurement
        return noisy.astype(np.float32)
