"""The simulated world: table, xArm 7 + gripper, a Femto Bolt-like camera and the scene's objects in MuJoCo.

The world frame is the robot base frame (z = 0 on the table top). Physics either follows the wall clock on
its own thread (`realtime`, like hardware: time passes whether or not anyone commands) or advances only when
`step()` is called (deterministic tests). All access to the MuJoCo data goes through `lock`.
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.config import CameraConfig, SimBoardConfig, SimConfig
from drivers.description import RobotSpec, load_robot_spec
from drivers.description.mjcf import add_robot
from drivers.sim.generate import scene_for
from drivers.sim.gl import mujoco
from drivers.sim.scene import Scene, add_object, expand_groups, place

TABLE_SIZE_M = (1.4, 1.6, 0.04)
TABLE_CENTER_XY_M = (0.3, 0.0)
CAMERA_NAME = "femto_bolt"
MAX_RENDER_SIZE = (1920, 1080)
PHYSICS_NICE = -10  # the real-time physics thread's nice value where permitted


def look_at(position: np.ndarray, target: np.ndarray) -> np.ndarray:
    """T_world_camera for an optical frame (x right, y down, z forward) at `position` looking at `target`."""
    z = np.asarray(target, float) - np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    if np.linalg.norm(x) < 1e-6:
        raise ValueError("camera looks straight down or up: choose a look_at point off the vertical")
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = position
    return T


def camera_fovy_deg(camera: CameraConfig) -> float:
    """Vertical field of view for square pixels given the configured horizontal one."""
    fx = (camera.width_px / 2) / math.tan(math.radians(camera.sim.horizontal_fov_deg) / 2)
    return math.degrees(2 * math.atan((camera.height_px / 2) / fx))


def camera_mount_pose(camera: CameraConfig) -> np.ndarray:
    """The camera's optical frame in its parent: T_world_camera, or T_flange_camera when flange-mounted."""
    if camera.sim.mount == "world":
        return look_at(np.array(camera.sim.position_m), np.array(camera.sim.look_at_m))
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", camera.sim.flange_rpy_rad).as_matrix()
    T[:3, 3] = camera.sim.flange_xyz_m
    return T


def add_board(parent: ET.Element, asset: ET.Element, board: SimBoardConfig) -> None:
    """A visual-only thin box whose +z face shows the board image (MuJoCo maps a 2d texture over each face with
    image x along the face's +x and image rows along its -y), placed so the board frame lands at board.xyz/rpy."""
    ET.SubElement(asset, "texture", name="tex_board", type="2d", file=str(Path(board.texture).resolve()))
    ET.SubElement(asset, "material", name="mat_board", texture="tex_board", specular="0", shininess="0")
    w, h = board.size_m
    T_parent_board = np.eye(4)
    T_parent_board[:3, :3] = Rotation.from_euler("xyz", board.rpy_rad).as_matrix()
    T_parent_board[:3, 3] = board.xyz_m
    T_geom_board = np.eye(4)  # board x = face x, board y = face -y, board z = -face normal, origin at a corner
    T_geom_board[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T_geom_board[:3, 3] = (-w / 2, h / 2, board.thickness_m / 2)
    T = T_parent_board @ np.linalg.inv(T_geom_board)
    x, y, z, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
    ET.SubElement(
        parent,
        "geom",
        name="calibration_board",
        type="box",
        size=f"{w / 2:.9g} {h / 2:.9g} {board.thickness_m / 2:.9g}",
        pos=" ".join(f"{v:.9g}" for v in T[:3, 3]),
        quat=f"{qw:.12g} {x:.12g} {y:.12g} {z:.12g}",
        material="mat_board",
        contype="0",
        conaffinity="0",
        mass="0",
    )


def build_mjcf(
    spec: RobotSpec, scene: Scene, poses: dict, camera: CameraConfig, dt: float, board: SimBoardConfig | None = None
) -> str:
    root = ET.Element("mujoco", model=f"goalvla_{scene.name}")
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", timestep=f"{dt:g}", integrator="implicitfast", cone="elliptic", impratio="10")
    visual = ET.SubElement(root, "visual")
    ET.SubElement(visual, "global", offwidth=str(MAX_RENDER_SIZE[0]), offheight=str(MAX_RENDER_SIZE[1]))
    ET.SubElement(visual, "quality", shadowsize="2048")
    ET.SubElement(visual, "headlight", ambient="0.35 0.35 0.35", diffuse="0.4 0.4 0.4", specular="0 0 0")
    asset = ET.SubElement(root, "asset")
    ET.SubElement(
        asset,
        "texture",
        name="tex_table",
        type="2d",
        builtin="checker",
        rgb1="0.62 0.48 0.34",
        rgb2="0.58 0.44 0.31",
        width="256",
        height="256",
        mark="edge",
        markrgb="0.55 0.42 0.3",
    )
    ET.SubElement(asset, "material", name="mat_table", texture="tex_table", texrepeat="8 8", specular="0.1")
    ET.SubElement(
        asset, "texture", name="tex_floor", type="2d", builtin="flat", rgb1="0.3 0.3 0.32", width="16", height="16"
    )
    ET.SubElement(asset, "material", name="mat_floor", texture="tex_floor")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", pos="0.4 0.3 2.2", dir="0 0 -1", diffuse="0.6 0.6 0.6", castshadow="true")
    ET.SubElement(world, "light", pos="1.5 -1.0 1.8", dir="-0.6 0.4 -0.7", diffuse="0.3 0.3 0.3", castshadow="false")
    ET.SubElement(
        world,
        "geom",
        name="floor",
        type="plane",
        size="3 3 0.1",
        pos="0 0 -0.75",
        material="mat_floor",
        contype="1",
        conaffinity="3",
    )
    sx, sy, sz = TABLE_SIZE_M
    ET.SubElement(
        world,
        "geom",
        name="table",
        type="box",
        size=f"{sx / 2} {sy / 2} {sz / 2}",
        pos=f"{TABLE_CENTER_XY_M[0]} {TABLE_CENTER_XY_M[1]} {-sz / 2}",
        material="mat_table",
        contype="1",
        conaffinity="3",
        friction="0.8 0.01 0.001",
    )
    actuators = ET.Element("actuator")
    add_robot(world, actuators, spec)
    flange = world.find(f".//body[@name='{spec.flange_link}']")
    flange_mounted = camera.sim.mount == "flange"
    T = camera_mount_pose(camera)
    x_mj, y_mj = T[:3, 0], -T[:3, 1]  # MuJoCo cameras look along -z with y up
    ET.SubElement(
        flange if flange_mounted else world,
        "camera",
        name=CAMERA_NAME,
        pos=" ".join(f"{v:.9g}" for v in T[:3, 3]),
        xyaxes=" ".join(f"{v:.9g}" for v in (*x_mj, *y_mj)),
        fovy=f"{camera_fovy_deg(camera):.9g}",
    )
    if board is not None:
        add_board(flange if board.mount == "flange" else world, asset, board)
    by_name = {o.name: o for o in scene.objects}
    for o in scene.objects:
        add_object(world, asset, o, poses[o.name], by_name.get(o.support))
    root.append(actuators)
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


class SimWorld:
    """Owns the MuJoCo model and data, the physics clock and the fault schedule shared by the sim devices."""

    def __init__(
        self, sim: SimConfig, camera: CameraConfig, spec: RobotSpec | None = None, home_q: np.ndarray | None = None
    ) -> None:
        self.config = sim
        self.camera_config = camera
        self.spec = spec or load_robot_spec()
        self.scene = expand_groups(scene_for(sim), sim.seed)
        self.poses = place(self.scene, sim.seed)
        self.xml = build_mjcf(self.spec, self.scene, self.poses, camera, sim.physics_dt_s, sim.board)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        self.lock = threading.RLock()
        # world-mounted camera: its fixed pose; flange-mounted (eye-in-hand): T_flange_camera, see camera_pose()
        self.T_world_camera = camera_mount_pose(camera) if camera.sim.mount == "world" else None
        self.T_flange_camera = camera_mount_pose(camera) if camera.sim.mount == "flange" else None
        m = self.model
        self.arm_qpos = np.array([m.jnt_qposadr[m.joint(n).id] for n in self.spec.joint_names])
        self.arm_dof = np.array([m.jnt_dofadr[m.joint(n).id] for n in self.spec.joint_names])
        self.arm_act = np.array([m.actuator(f"servo_{n}").id for n in self.spec.joint_names])
        self.arm_vel_act = np.array([m.actuator(f"velocity_{n}").id for n in self.spec.joint_names])
        fingers = self.spec.gripper.finger_joints
        self.finger_qpos = np.array([m.jnt_qposadr[m.joint(n).id] for n in fingers])
        self.finger_act = np.array([m.actuator(f"servo_{n}").id for n in fingers])
        self._post_step: list[Callable[[], None]] = []
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self.reset(np.asarray(home_q if home_q is not None else self.spec.home_q, dtype=float))

    # -- state --------------------------------------------------------------------------------------------
    def reset(self, q: np.ndarray) -> None:
        """Put the arm at q (holding it there), fingers open, objects at their seeded poses, then settle."""
        with self.lock:
            mujoco.mj_resetData(self.model, self.data)
            self.data.qpos[self.arm_qpos] = q
            self.data.ctrl[self.arm_act] = q
            open_half = self.spec.gripper.max_width_m / 2
            self.data.qpos[self.finger_qpos] = open_half
            self.data.ctrl[self.finger_act] = open_half
            for o in self.scene.objects:
                if o.kind == "lidded_box":
                    hinge = self.model.joint(f"{o.name}_hinge")
                    self.data.qpos[hinge.qposadr[0]] = math.radians(o.lid_open_deg)
            mujoco.mj_forward(self.model, self.data)
            for _ in range(int(0.3 / self.model.opt.timestep)):  # let objects settle on the table
                mujoco.mj_step(self.model, self.data)
            self.data.time = 0.0

    @property
    def time(self) -> float:
        return float(self.data.time)

    def add_post_step_hook(self, hook: Callable[[], None]) -> None:
        """Called (under the lock) after every physics step: devices use it for scheduled faults."""
        self._post_step.append(hook)

    def object_pose(self, name: str) -> np.ndarray:
        """Ground-truth T_base_object of a scene object (its body frame)."""
        with self.lock:
            body = self.data.body(name)
            T = np.eye(4)
            T[:3, :3] = body.xmat.reshape(3, 3)
            T[:3, 3] = body.xpos
            return T

    def displace(self, name: str, dx_m: float, dy_m: float, dyaw_rad: float = 0.0) -> None:
        """Move a free object on the table as a person would nudge it: shifted by (dx, dy) and turned about the
        vertical through its centre, at rest; the physics settles it from there (tests of a scene that changed)."""
        joint = self.model.joint(f"{name}_free")
        adr, dof = joint.qposadr[0], joint.dofadr[0]
        with self.lock:
            qpos = self.data.qpos
            qpos[adr : adr + 2] += (dx_m, dy_m)
            turn = np.array([math.cos(dyaw_rad / 2), 0.0, 0.0, math.sin(dyaw_rad / 2)])
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, turn, qpos[adr + 3 : adr + 7].copy())
            qpos[adr + 3 : adr + 7] = quat
            self.data.qvel[dof : dof + 6] = 0.0
            mujoco.mj_forward(self.model, self.data)

    def camera_pose(self) -> np.ndarray:
        """Ground-truth T_world_camera now (it moves with the flange when the camera is mounted there)."""
        if self.T_flange_camera is None:
            return self.T_world_camera.copy()
        with self.lock:
            body = self.data.body(self.spec.flange_link)
            T_world_flange = np.eye(4)
            T_world_flange[:3, :3] = body.xmat.reshape(3, 3)
            T_world_flange[:3, 3] = body.xpos
        return T_world_flange @ self.T_flange_camera

    def tcp_pose(self) -> np.ndarray:
        with self.lock:
            site = self.data.site("tcp")
            T = np.eye(4)
            T[:3, :3] = site.xmat.reshape(3, 3)
            T[:3, 3] = site.xpos
            return T

    # -- time ---------------------------------------------------------------------------------------------
    def _step_once(self) -> None:
        mujoco.mj_step(self.model, self.data)
        for hook in self._post_step:
            hook()

    def step(self, seconds: float) -> None:
        """Advance physics by `seconds` (only when not running in real time)."""
        if self._thread is not None:
            raise RuntimeError("SimWorld.step() is for non-realtime worlds; this one runs on its own clock")
        with self.lock:
            for _ in range(max(1, round(seconds / self.model.opt.timestep))):
                self._step_once()

    def start(self) -> None:
        """Run physics against the wall clock on a background thread (idempotent)."""
        if self._thread is not None:
            return
        self._running.set()
        self._thread = threading.Thread(target=self._run, name="sim-physics", daemon=True)
        self._thread.start()

    @property
    def physics_thread_id(self) -> int | None:
        """The OS thread id of the real-time physics thread (None before start() or when stepped)."""
        return self._thread.native_id if self._thread is not None else None

    def stop(self) -> None:
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None

    def _run(self) -> None:
        # the twin stands for the robot, which keeps time whatever the PC's load: a higher share of the CPU where
        # permitted (a nicer-than-normal thread, not a real-time one: a real-time thread holding the GIL would
        # starve the process's other threads, the Zenoh callbacks that receive heartbeats among them)
        with contextlib.suppress(OSError, AttributeError):
            os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), PHYSICS_NICE)
        dt = self.model.opt.timestep
        t0_wall, t0_sim = time.perf_counter(), self.data.time
        while self._running.is_set():
            target = t0_sim + (time.perf_counter() - t0_wall)
            with self.lock:
                behind = int((target - self.data.time) / dt)
                if behind > 200:  # more than 0.4 s behind (machine stalled): drop time rather than spiral
                    t0_wall, t0_sim = time.perf_counter(), self.data.time
                    behind = 1
                for _ in range(behind):
                    self._step_once()
            time.sleep(dt / 2)


class SteppedClock:
    """The executor's clock (motion.clock.Clock) for a non-realtime world: waiting for a time steps the physics
    to it, so streaming in tests and benchmarks runs as fast as the machine allows and is repeatable."""

    def __init__(self, world: SimWorld) -> None:
        self.world = world

    def now(self) -> float:
        return self.world.time

    def sleep_until(self, t: float) -> None:
        if t > self.world.time + 1e-9:
            self.world.step(t - self.world.time)
