"""Initial/goal image pairs rendered in the simulator with a known object motion (benchmarks and tests).

One object is moved by setting its free joint in a non-realtime world (no physics step, so the pose is
exactly the one asked for) and the scene is rendered again. The goal depth is then handed over as a model
would: an unknown affine map of depth or of disparity, plus noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.sim.camera import SimCamera
from drivers.sim.gl import mujoco
from drivers.sim.world import SimWorld
from drivers.types import CameraIntrinsics
from pipeline.grounding.depth_align import DepthKind


@dataclass(frozen=True)
class SimPair:
    rgb0: np.ndarray
    depth0: np.ndarray  # metric, NaN invalid
    mask0: np.ndarray
    rgb1: np.ndarray
    depth1: np.ndarray  # relative prediction (affine of depth or disparity, noisy)
    depth1_kind: DepthKind
    mask1: np.ndarray
    intrinsics: CameraIntrinsics
    T_base_camera: np.ndarray
    T_motion_camera: np.ndarray  # true x_goal = T x_init in the camera frame
    centre_camera: np.ndarray  # true object centre at the initial pose, camera frame [m]
    T_camera_object0: np.ndarray  # true initial object pose in the camera frame
    object_name: str
    object_kind: str

    def as_npz_dict(self) -> dict[str, np.ndarray]:
        """The `goalvla ground` input layout (PAIR.npz)."""
        depth0 = np.nan_to_num(self.depth0, nan=0.0).astype(np.float32)
        return {
            "rgb0": self.rgb0,
            "depth0": depth0,
            "mask0": self.mask0,
            "rgb1": self.rgb1,
            "depth1": self.depth1.astype(np.float32),
            "depth1_kind": np.array(self.depth1_kind),
            "mask1": self.mask1,
            "K": self.intrinsics.K,
        }


class PairRenderer:
    """Renders pairs from one world; the world is restored to its initial state before each pair."""

    def __init__(self, world: SimWorld, camera_seed: int = 0) -> None:
        if world.config.realtime:
            raise ValueError("PairRenderer needs a non-realtime world (sim.realtime: false)")
        self.world = world
        self.camera = SimCamera(world, seed=camera_seed)
        self.camera.connect()
        self.qpos0 = world.data.qpos.copy()
        self.T_base_camera = self.camera.T_base_camera

    def close(self) -> None:
        self.camera.close()

    def movable(self) -> list[str]:
        return [o.name for o in self.world.scene.objects if not o.is_fixed()]

    def _set_pose(self, name: str, T_base_object: np.ndarray) -> None:
        w = self.world
        adr = w.model.jnt_qposadr[w.model.joint(f"{name}_free").id]
        q = Rotation.from_matrix(T_base_object[:3, :3]).as_quat(scalar_first=True)
        w.data.qpos[adr : adr + 3] = T_base_object[:3, 3]
        w.data.qpos[adr + 3 : adr + 7] = q
        mujoco.mj_kinematics(w.model, w.data)

    def _lowest_z(self, name: str) -> float:
        """Lowest point of the object's geoms in the base frame: exact for spheres, capsules, cylinders, ellipsoids
        and boxes, a geom's bounding box otherwise. A rotated bounding box's lowest corner lies below a round
        geom's lowest point, and the goal set on it floated: a ball tipped by 45 deg hovered 26 mm over the table."""
        m, d = self.world.model, self.world.data
        root = m.body(name).id
        zs = []
        for g in np.flatnonzero(m.body_rootid[m.geom_bodyid] == root):
            size, down = m.geom_size[g], d.geom_xmat[g].reshape(3, 3)[2]  # the geom's axes' heights (world z row)
            kind = m.geom_type[g]
            if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                reach = size[0]
            elif kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
                reach = size[1] * abs(down[2]) + size[0]
            elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
                reach = size[1] * abs(down[2]) + size[0] * math.sqrt(max(0.0, 1.0 - down[2] ** 2))
            elif kind == mujoco.mjtGeom.mjGEOM_ELLIPSOID:
                reach = float(np.linalg.norm(size * down))
            elif kind == mujoco.mjtGeom.mjGEOM_BOX:
                reach = float(np.abs(down) @ size)
            else:
                c, half = m.geom_aabb[g, :3], m.geom_aabb[g, 3:]
                corners = c + half * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
                zs.append((corners @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g])[:, 2].min())
                continue
            zs.append(d.geom_xpos[g][2] - reach)
        return float(min(zs))

    def _centre(self, name: str) -> np.ndarray:
        m, d = self.world.model, self.world.data
        geoms = np.flatnonzero(m.body_rootid[m.geom_bodyid] == m.body(name).id)
        return d.geom_xpos[geoms].mean(axis=0)

    def random_goal(
        self, name: str, rng: np.random.Generator, max_shift_m: float, max_yaw_deg: float, max_tilt_deg: float
    ) -> np.ndarray | None:
        """A goal pose: shifted on the table, yawed, tilted about a horizontal axis, resting on the table."""
        T0 = self.world.object_pose(name)
        c0 = self._centre(name)
        shift = rng.uniform(0, max_shift_m)
        heading = rng.uniform(0, 2 * math.pi)
        xy = c0[:2] + shift * np.array([math.cos(heading), math.sin(heading)])
        if not (0.28 <= xy[0] <= 0.78 and -0.36 <= xy[1] <= 0.36):
            return None
        tilt_axis = rng.uniform(0, 2 * math.pi)
        R_tilt = Rotation.from_rotvec(
            math.radians(rng.uniform(0, max_tilt_deg)) * np.array([math.cos(tilt_axis), math.sin(tilt_axis), 0.0])
        )
        R_yaw = Rotation.from_euler("z", rng.uniform(-max_yaw_deg, max_yaw_deg), degrees=True)
        R = (R_tilt * R_yaw).as_matrix()
        T1 = np.eye(4)
        T1[:3, :3] = R @ T0[:3, :3]
        T1[:3, 3] = R @ (T0[:3, 3] - c0) + np.array([xy[0], xy[1], c0[2]])
        return T1

    def render(
        self,
        name: str,
        T_base_goal: np.ndarray,
        depth_kind: DepthKind,
        rng: np.random.Generator,
        pred_noise_rel: float = 0.002,
        min_pixels: int = 150,
    ) -> SimPair | None:
        """Render the initial scene and the scene with `name` at T_base_goal (lifted to rest on the table)."""
        w = self.world
        with w.lock:
            w.data.qpos[:] = self.qpos0
            mujoco.mj_kinematics(w.model, w.data)
            T0 = w.object_pose(name)
            centre0 = self._centre(name)
            f0 = self.camera.read()
            masks0 = self.camera.object_masks()
            self._set_pose(name, T_base_goal)
            T1 = T_base_goal.copy()
            T1[2, 3] -= self._lowest_z(name) - 0.0005
            self._set_pose(name, T1)
            if self._collides(name):
                w.data.qpos[:] = self.qpos0
                return None
            f1 = self.camera.read()
            masks1 = self.camera.object_masks()
            w.data.qpos[:] = self.qpos0
            mujoco.mj_kinematics(w.model, w.data)
        m0, m1 = masks0[name], masks1[name]
        if m0.sum() < min_pixels or m1.sum() < min_pixels or _touches_border(m1) or _touches_border(m0):
            return None
        Tcb = np.linalg.inv(self.T_base_camera)
        motion_base = T1 @ np.linalg.inv(T0)
        kind_name = next(o.kind for o in w.scene.objects if o.name == name)
        return SimPair(
            f0.rgb,
            f0.depth,
            m0,
            f1.rgb,
            _relative_prediction(f1.depth, depth_kind, rng, pred_noise_rel),
            depth_kind,
            m1,
            f0.intrinsics,
            self.T_base_camera,
            Tcb @ motion_base @ self.T_base_camera,
            (Tcb @ np.append(centre0, 1.0))[:3],
            Tcb @ T0,
            name,
            kind_name,
        )

    def _collides(self, name: str) -> bool:
        """True when the moved object penetrates another body (other than the table, which it rests on)."""
        m, d = self.world.model, self.world.data
        mujoco.mj_forward(m, d)
        root = m.body(name).id
        for c in d.contact[: d.ncon]:
            b1, b2 = m.body_rootid[m.geom_bodyid[c.geom1]], m.body_rootid[m.geom_bodyid[c.geom2]]
            if root in (b1, b2) and (b1 != b2) and min(b1, b2) != 0 and c.dist < -0.002:
                return True
        return False


def _touches_border(mask: np.ndarray) -> bool:
    return bool(mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())


def _relative_prediction(
    depth_m: np.ndarray, kind: DepthKind, rng: np.random.Generator, noise_rel: float
) -> np.ndarray:
    """What a monocular model might return: an unknown affine map of depth (or disparity) with noise."""
    d = depth_m.astype(np.float64)
    if kind == "disparity":
        x = 1.0 / d
        x = x * (1.0 + rng.normal(0, noise_rel, d.shape))
        s, b = rng.uniform(0.5, 5.0), rng.uniform(-0.3, 0.3)
    else:
        x = d * (1.0 + rng.normal(0, noise_rel, d.shape))
        s, b = rng.uniform(0.2, 3.0), rng.uniform(-1.0, 1.0)
    return (s * x + b).astype(np.float32)
