"""The xArm controller's wire format, as the installed xarm-python-sdk (1.18) speaks it; written from reading the SDK.

Commands (TCP 502) are Modbus-TCP-like frames: a big-endian header (transaction id, protocol id 2 or 3, length of
what follows the length field, register), then the arguments. A reply repeats the header, adds one status byte
and the results. Numbers: floats are little-endian float32, integers big-endian, except the TCP boundary (six
little-endian int32). The status byte carries the controller's condition on every reply: an uncleared error
(0x40), an uncleared warning (0x20), not ready to move (0x10), the command was invalid (0x08); the SDK turns them
into API codes 1, 2, 9 and 10. A frame with register 0xFF is a feedback message (a queued command finished).

The 'real' state report (TCP 30003, 100 Hz) is a big-endian uint32 frame size, then state (low nibble) and mode
(high nibble) in one byte, the command-cache count, 7 joint angles [rad], the TCP pose [mm, rad] and 7 joint
torques [N m], floats little-endian: 87 bytes. It carries neither joint speeds nor error or warning codes; those
come from the replies' status byte and get_err_warn_code.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum, IntFlag

HEADER = struct.Struct(">HHHB")  # transaction id, protocol id, length (bytes after this field), register
PRIVATE_PROTOCOLS = (2, 3)  # the SDK starts with 2 and switches to 3 (with heartbeats) on firmware >= 1.8.6
MAX_FRAME_BYTES = 1024  # the SDK's command buffer; a longer frame is a framing error
FEEDBACK_REGISTER = 0xFF
COMMAND_PORT = 502
REPORT_PORT = 30003
REPORT_BYTES = 87


class Register(IntEnum):
    """The registers the driver and `goalvla doctor` use (and the SDK calls they imply)."""

    GET_VERSION = 1
    GET_ROBOT_SN = 2
    MOTION_ENABLE = 11
    SET_STATE = 12
    GET_STATE = 13
    GET_CMDNUM = 14
    GET_ERROR = 15
    CLEAN_ERROR = 16
    CLEAN_WARN = 17
    SET_MODE = 19
    SERVO_J = 29
    SET_TCP_OFFSET = 35
    SET_PAYLOAD = 36
    SET_COLLISION_SENSITIVITY = 37
    GET_TCP_POSE = 41
    GET_JOINTS = 42
    SET_REDUCED_TCP_SPEED = 47
    SET_REDUCED_JOINT_SPEED = 48
    GET_REDUCED_MODE = 49
    SET_REDUCED_MODE = 50
    SET_TCP_BOUNDARY = 52
    GET_REDUCED_STATE = 53
    SET_FENCE = 59
    SET_COLLISION_REBOUND = 60
    SET_SELF_COLLISION = 77
    SET_COLLISION_TOOL = 78
    TOOL_RS485 = 124  # a Modbus-RTU request tunnelled to a device on the tool's RS-485 bus (the gripper)
    TOOL_READ16 = 128  # a register of the tool-side RS-485 host (its baud rate)
    FEEDBACK_CHECK = 253
    SET_FEEDBACK_TYPE = 254


class Status(IntFlag):
    OK = 0
    INVALID = 0x08
    NOT_READY = 0x10
    WARNING = 0x20
    ERROR = 0x40


class FramingError(ValueError):
    """The byte stream cannot be split into frames (a length field out of range)."""


@dataclass(frozen=True)
class Request:
    transaction: int
    protocol: int
    register: int
    payload: bytes


class FrameReader:
    """Splits a TCP byte stream into requests (frames may arrive split or glued together)."""

    def __init__(self) -> None:
        self._buffer = b""

    def feed(self, data: bytes) -> list[Request]:
        self._buffer += data
        out = []
        while len(self._buffer) >= HEADER.size:
            transaction, protocol, length, register = HEADER.unpack_from(self._buffer)
            if not 1 <= length <= MAX_FRAME_BYTES:
                raise FramingError(f"frame length field {length} outside 1..{MAX_FRAME_BYTES}")
            end = 6 + length
            if len(self._buffer) < end:
                break
            out.append(Request(transaction, protocol, register, self._buffer[HEADER.size : end]))
            self._buffer = self._buffer[end:]
        return out


def reply(request: Request, status: Status, payload: bytes = b"") -> bytes:
    """The controller's answer to `request`: same transaction, protocol and register, status, results."""
    return (
        HEADER.pack(request.transaction, request.protocol, len(payload) + 2, request.register)
        + bytes([int(status)])
        + payload
    )


def feedback(request: Request, kind: int, code: int = 0) -> bytes:
    """'The command of this transaction finished' (kind: the SDK's feedback type bit; code 0 success)."""
    body = bytes([0, kind, 0, 0, request.register, code])
    return HEADER.pack(request.transaction, request.protocol, len(body) + 1, FEEDBACK_REGISTER) + body


def floats(payload: bytes, n: int) -> list[float]:
    if len(payload) < 4 * n:
        raise ValueError(f"need {n} float32 arguments, got {len(payload)} bytes")
    return list(struct.unpack_from(f"<{n}f", payload))


def pack_floats(values: Sequence[float]) -> bytes:
    return struct.pack(f"<{len(values)}f", *values)


def int32s_le(payload: bytes, n: int) -> list[int]:
    if len(payload) < 4 * n:
        raise ValueError(f"need {n} int32 arguments, got {len(payload)} bytes")
    return list(struct.unpack_from(f"<{n}i", payload))


def real_report(
    state: int, mode: int, cmdnum: int, q_rad: Sequence[float], tcp_pose: Sequence[float], torque: Sequence[float]
) -> bytes:
    """One 'real' report frame; tcp_pose is [x, y, z mm, roll, pitch, yaw rad]."""
    frame = struct.pack(">IBH", REPORT_BYTES, (mode << 4) | (state & 0x0F), cmdnum)
    frame += pack_floats([*q_rad, *tcp_pose, *torque])
    if len(frame) != REPORT_BYTES:
        raise ValueError(f"report of {len(frame)} bytes, expected {REPORT_BYTES} (7 joints, 6 pose, 7 torques)")
    return frame
