"""Open the devices a profile names, all or nothing, and find T_base_camera for the captures."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass

import numpy as np

from calibration.store import load_calibration
from drivers.interfaces import Arm, Camera, Gripper
from runtime.config import Profile

log = logging.getLogger(__name__)


class DeviceSetupError(RuntimeError):
    pass


@dataclass
class Devices:
    camera: Camera
    arm: Arm
    gripper: Gripper
    T_base_camera: np.ndarray | None  # None only when opened with_extrinsics=False (hand-eye calibration)
    world: object | None = None  # the SimWorld on the sim profile (ground truth for tests and verification)


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


def camera_extrinsics(profile: Profile, world: object | None) -> np.ndarray:
    """T_base_camera from the calibration file, or on the sim without one, the simulated camera's true pose."""
    cal = profile.calibration
    if cal.file is not None:
        calibration = load_calibration(cal.file)
        if calibration.mode != "eye_to_hand":
            raise DeviceSetupError(f"{cal.file}: captures need an eye-to-hand calibration, got {calibration.mode}")
        if calibration.age_days() > cal.max_age_days:
            log.warning(
                "calibration %s is %.0f days old (limit %.0f): recalibrate",
                cal.file,
                calibration.age_days(),
                cal.max_age_days,
            )
        return calibration.matrix
    if world is not None:
        return world.camera_pose()
    raise DeviceSetupError("calibration.file is not set: run `goalvla calibrate hand-eye` and set it in the profile")


@contextmanager
def open_devices(profile: Profile, *, with_extrinsics: bool = True) -> Iterator[Devices]:
    """Connect camera, arm and gripper; on any failure close what was opened. Always closes (arm stopped).
    with_extrinsics=False skips the calibration lookup (for the calibration itself)."""
    sim = profile.robot.kind == "sim" and profile.camera.kind == "sim"
    camera, arm, gripper, world = _sim_devices(profile) if sim else _hardware_devices(profile)
    T_base_camera = camera_extrinsics(profile, world) if with_extrinsics else None
    with ExitStack() as stack:
        for device in (arm, gripper, camera):
            device.connect()
            stack.callback(device.close)
        try:
            yield Devices(camera, arm, gripper, T_base_camera, world)
        finally:
            if world is not None:
                stack.callback(world.stop)
