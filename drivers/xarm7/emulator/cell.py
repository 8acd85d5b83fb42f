"""An emulated cell: the MuJoCo twin, the controller emulator over it, and the devices a profile drives there (the
real XArm7 + XArmGripper through the SDK to the emulator, the SimCamera rendering the same world); and the
emulator alone for `goalvla emulator`."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.config import CameraConfig, RobotConfig, SimConfig
from drivers.sim import SimCamera, SimWorld
from drivers.xarm7.arm import XArm7
from drivers.xarm7.emulator.emulator import XArmEmulator
from drivers.xarm7.gripper import XArmGripper


@dataclass
class EmulatedCell:
    world: SimWorld
    emulator: XArmEmulator
    camera: SimCamera
    arm: XArm7
    gripper: XArmGripper

    @classmethod
    def start(cls, robot: RobotConfig, safety: Any, sim: SimConfig, camera: CameraConfig) -> EmulatedCell:
        """World and emulator running at robot.ip (EmulatorBindError if its ports are taken); devices not
        connected yet. `safety` is the profile's SafetyConfig (the driver writes it to the controller)."""
        if not robot.emulated:
            raise ValueError("EmulatedCell needs a robot section with emulated: true")
        home = np.asarray(robot.home_q_rad) if robot.home_q_rad else None
        world = SimWorld(sim, camera, home_q=home)
        emulator = XArmEmulator(world, str(robot.ip), robot.control_rate_hz)
        try:
            emulator.start()
        except BaseException:
            world.stop()
            raise
        arm = XArm7(robot, safety, spec=world.spec)
        return cls(world, emulator, SimCamera(world, seed=sim.seed), arm, XArmGripper(arm))

    def stop(self) -> None:
        """After the devices closed: the emulator's ports, then the physics thread."""
        self.emulator.stop()
        self.world.stop()


def serve(
    sim: SimConfig,
    camera: CameraConfig,
    address: str | None,
    control_rate_hz: float,
    echo: Callable[[str], None],
    stop: threading.Event,
) -> None:
    """`goalvla emulator`: a controller for any SDK client (scripts, xArm tools) until `stop` is set or Ctrl-C."""
    world = SimWorld(sim, camera)
    try:
        with XArmEmulator(world, address, control_rate_hz) as emulator:
            echo(
                f"xArm 7 controller emulator on {emulator.address} (commands :502, 'real' report :30003), "
                f"scene {sim.scene} seed {sim.seed}; Ctrl-C stops"
            )
            try:
                while not stop.wait(0.2):
                    pass
            except KeyboardInterrupt:
                pass
            j = emulator.journal
            echo(f"served {len(j.accepted())} set-points, {len(j.errors)} controller errors, {len(j.stops)} stops")
    finally:
        world.stop()
