"""An xArm 7 controller emulator speaking xarm-python-sdk's protocol on loopback, over the MuJoCo twin.

wire.py (frames, registers, the 'real' report), tool_bus.py (the gripper on the tool's RS-485 bus),
controller.py (modes, states, errors, controller-side safety), handlers.py (one function per register),
faults.py (protocol faults for tests), server.py (TCP 502 and 30003), emulator.py (the whole controller).
"""

from drivers.xarm7.emulator.emulator import XArmEmulator
from drivers.xarm7.emulator.server import EmulatorBindError

__all__ = ["EmulatorBindError", "XArmEmulator"]
