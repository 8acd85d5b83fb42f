"""Open the devices a profile names, all or nothing, and capture frames with the camera pose they were taken from.

The camera pose comes from the hand-eye calibration: fixed (eye-to-hand), or carried by the arm (eye-in-hand:
T_base_flange at the capture, from the measured joints, times T_flange_camera; the arm must hold still while the
frame is taken). On the sim without a calibration file it is the simulated camera's true pose.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass

import numpy as np

from calibration.store import load_calibration
from drivers.interfaces import Arm, Camera, Gripper
from drivers.optional import missing_package
from drivers.types import RGBDFrame
from runtime.config import Profile

log = logging.getLogger(__name__)

STILL_RAD = 1e-3  # eye-in-hand: the largest joint change between before and after a frame that counts as still

CameraPose = Callable[[np.ndarray], np.ndarray]  # measured joints -> T_base_camera


class DeviceSetupError(RuntimeError):
    pass


class CaptureError(RuntimeError):
    """A frame whose camera pose is not known (the arm carrying the camera moved while it was taken)."""


@dataclass
class Devices:
    camera: Camera
    arm: Arm
    gripper: Gripper
    camera_pose: CameraPose | None  # None only when opened with_extrinsics=False (hand-eye calibration)
    world: object | None = None  # the SimWorld on the sim profile (ground truth for tests and verification)
    moving_camera: bool = False  # eye-in-hand: the pose depends on the arm's joints

    def capture(self, timeout_s: float | None = None) -> RGBDFrame:
        """One RGB-D frame with T_base_camera as it was when the frame was taken."""
        if self.camera_pose is None:
            raise DeviceSetupError("devices opened without camera extrinsics (hand-eye calibration mode)")
        q_before = self.arm.read_state().q
        frame = self.camera.read() if timeout_s is None else self.camera.read(timeout_s)
        q_after = self.arm.read_state().q
        moved = float(np.max(np.abs(q_after - q_before)))
        if self.moving_camera and moved > STILL_RAD:
            raise CaptureError(
                f"the arm carrying the camera moved {moved:.4f} rad while the frame was taken (still: <= {STILL_RAD})"
            )
        return frame.with_extrinsics(self.camera_pose(q_after))


SDKS = {"xarm7": ("xarm", "xarm-python-sdk"), "femto_bolt": ("pyorbbecsdk", "pyorbbecsdk2")}  # kind -> (module, dist)


def missing_device_packages(profile: Profile) -> list[str]:
    """The SDKs the profile's robot and camera need that are not installed (checked at start-up)."""
    kinds = (("robot.kind", profile.robot.kind), ("camera.kind", profile.camera.kind))
    problems = (missing_package(*SDKS[kind], f"{key} {kind}") for key, kind in kinds if kind in SDKS)
    return [p for p in problems if p is not None]


def _sim_devices(profile: Profile) -> tuple[Camera, Arm, Gripper, object]:
    from drivers.sim import SimArm, SimCamera, SimGripper, SimWorld

    home = np.asarray(profile.robot.home_q_rad) if profile.robot.home_q_rad else None
    world = SimWorld(profile.sim, profile.camera, home_q=home)
    camera = SimCamera(world, seed=profile.sim.seed)
    return camera, SimArm(world, profile.robot.control_rate_hz), SimGripper(world), world


def _hardware_devices(profile: Profile) -> tuple[Camera, Arm, Gripper, None]:
    """xArm 7 + gripper and Femto Bolt (their SDKs are imported on connect). Sim and hardware do not mix."""
    if profile.robot.kind != "xarm7" or profile.camera.kind != "femto_bolt":
        raise DeviceSetupError(
            f"robot.kind {profile.robot.kind!r} with camera.kind {profile.camera.kind!r}: use both simulated "
            "(sim/sim) or both real (xarm7/femto_bolt); the simulated camera renders the simulated arm only"
        )
    from drivers.femto_bolt import FemtoBolt
    from drivers.xarm7 import XArm7, XArmGripper

    arm = XArm7(profile.robot, profile.safety)
    return FemtoBolt(profile.camera), arm, XArmGripper(arm), None


def _emulated_cell(profile: Profile):
    """The real xArm driver against the controller emulator at robot.ip over the twin; the SimCamera sees it."""
    if profile.camera.kind != "sim":
        raise DeviceSetupError("robot.emulated drives the MuJoCo twin: camera.kind must be 'sim' to see it")
    from drivers.xarm7.emulator.cell import EmulatedCell

    return EmulatedCell.start(profile.robot, profile.safety, profile.sim, profile.camera)


def camera_extrinsics(profile: Profile, world: object | None) -> tuple[CameraPose, bool]:
    """(joints -> T_base_camera, whether it depends on the joints) from the calibration file, or on the sim without
    one, the simulated camera's true pose."""
    cal = profile.calibration
    if cal.file is not None:
        calibration = load_calibration(cal.file)
        if calibration.age_days() > cal.max_age_days:
            log.warning(
                "calibration %s is %.0f days old (limit %.0f): recalibrate",
                cal.file,
                calibration.age_days(),
                cal.max_age_days,
            )
        T = calibration.matrix
        if calibration.mode == "eye_to_hand":
            return (lambda q: T.copy()), False
        from safety.robot_model import RobotModel

        robot = RobotModel()
        return (lambda q: robot.frame_pose(q, robot.spec.flange_link) @ T), True
    if world is not None:
        return (lambda q: world.camera_pose()), world.T_flange_camera is not None
    raise DeviceSetupError("calibration.file is not set: run `goalvla calibrate hand-eye` and set it in the profile")


@contextmanager
def open_devices(profile: Profile, *, with_extrinsics: bool = True) -> Iterator[Devices]:
    """Connect camera, arm and gripper; on any failure close what was opened. Always closes (arm stopped).
    with_extrinsics=False skips the calibration lookup (for the calibration itself)."""
    sim = profile.robot.kind == "sim" and profile.camera.kind == "sim"
    cell = _emulated_cell(profile) if profile.robot.emulated else None
    if cell is not None:
        camera, arm, gripper, world = cell.camera, cell.arm, cell.gripper, cell.world
    else:
        camera, arm, gripper, world = _sim_devices(profile) if sim else _hardware_devices(profile)
    with ExitStack() as stack:
        if cell is not None:
            stack.callback(cell.stop)  # first in, last out: the emulator serves the devices' close
        camera_pose, moving = camera_extrinsics(profile, world) if with_extrinsics else (None, False)
        for device in (arm, gripper, camera):
            device.connect()
            stack.callback(device.close)
        try:
            yield Devices(camera, arm, gripper, camera_pose, world, moving)
        finally:
            if world is not None:
                stack.callback(world.stop)
