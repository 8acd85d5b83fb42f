"""The tool's RS-485 bus as the SDK reaches the xArm Gripper through the controller: Modbus-RTU requests (function
0x03 read registers, 0x10 write registers) tunnelled in TOOL_RS485 commands, each prefixed with the bus host id
(9, the robot's tool connector) and addressed to the gripper (device 8). Values are big-endian 16-bit registers;
positions are two registers (int32)."""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Protocol

HOST_ID = 9
GRIPPER_ID = 8
READ_REGISTERS = 0x03
WRITE_REGISTERS = 0x10
BAUD_REGISTER = 0x0A0B  # read with TOOL_READ16 from the host: the bus baud rate as an index
BAUD_INDEX_2M = 11  # the SDK's table index of 2 Mbaud, the xArm Gripper's rate (anything else makes it re-set it)


class GripperRegisters(Protocol):
    def read_register(self, address: int) -> int: ...

    def write_register(self, address: int, value: int) -> None: ...


@dataclass(frozen=True)
class BusReply:
    payload: bytes
    ok: bool  # False: a request this bus does not answer (the controller's reply is then marked invalid)


def handle(payload: bytes, gripper: GripperRegisters) -> BusReply:
    """Answer one tunnelled request (payload: host id, device id, function, arguments)."""
    if len(payload) < 7 or payload[0] != HOST_ID or payload[1] != GRIPPER_ID:
        return BusReply(payload[:2], False)
    function = payload[2]
    address, count = struct.unpack_from(">HH", payload, 3)
    head = payload[:3]
    if function == READ_REGISTERS:
        words = [gripper.read_register(address + i) & 0xFFFF for i in range(count)]
        return BusReply(head + bytes([2 * count]) + struct.pack(f">{count}H", *words), True)
    if function == WRITE_REGISTERS and len(payload) >= 8 + 2 * count:
        words = struct.unpack_from(f">{count}H", payload, 8)
        value = 0
        for word in words:  # one value across `count` registers, most significant first
            value = (value << 16) | word
        if count == 2:
            value = struct.unpack(">i", struct.pack(">I", value))[0]
        gripper.write_register(address, value)
        return BusReply(head + struct.pack(">HH", address, count), True)
    return BusReply(head, False)


def read_host_register(payload: bytes) -> tuple[bool, bytes]:
    """TOOL_READ16 (host id, register): only the baud rate is emulated."""
    if len(payload) >= 3 and payload[0] == HOST_ID and struct.unpack_from(">H", payload, 1)[0] == BAUD_REGISTER:
        return True, struct.pack(">i", BAUD_INDEX_2M)
    return False, b""
