"""UFACTORY xArm 7 + xArm Gripper on xarm-python-sdk (imported lazily, only when a connection is made)."""

from drivers.xarm7.arm import XArm7
from drivers.xarm7.gripper import XArmGripper

__all__ = ["XArm7", "XArmGripper"]
