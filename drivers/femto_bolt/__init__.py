"""Orbbec Femto Bolt on pyorbbecsdk (PyPI pyorbbecsdk2, installed --no-deps; imported only on connect)."""

from drivers.femto_bolt.camera import CameraSetupError, FemtoBolt
from drivers.femto_bolt.streams import DEPTH_MODES, intrinsics_problems

__all__ = ["DEPTH_MODES", "CameraSetupError", "FemtoBolt", "intrinsics_problems"]
