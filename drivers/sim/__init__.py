"""MuJoCo twin of the lab: world, simulated xArm 7 + gripper and Femto Bolt, scenes."""

from drivers.sim.arm import SimArm, SimGripper
from drivers.sim.camera import SimCamera
from drivers.sim.world import SimWorld, SteppedClock

__all__ = ["SimArm", "SimCamera", "SimGripper", "SimWorld", "SteppedClock"]
