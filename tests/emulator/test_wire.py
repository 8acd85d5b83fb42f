"""The wire codec on its own: framing of a byte stream, the reply and feedback layouts the SDK reads, the 'real'
report decoded by the SDK's own report structure, and the gripper's tunnelled Modbus registers."""

from __future__ import annotations

import contextlib
import io
import struct

import numpy as np
import pytest

from drivers.xarm7.emulator import tool_bus
from drivers.xarm7.emulator.wire import (
    REPORT_BYTES,
    FrameReader,
    FramingError,
    Register,
    Request,
    Status,
    feedback,
    real_report,
    reply,
)

with contextlib.redirect_stdout(io.StringIO()):
    from xarm.x3.report import ReportDataStructure


def _request(transaction: int, register: int, payload: bytes = b"", protocol: int = 2) -> bytes:
    return struct.pack(">HHHB", transaction, protocol, len(payload) + 1, register) + payload


def test_frames_split_and_glued_in_a_stream_come_out_whole():
    stream = _request(1, Register.GET_STATE) + _request(2, Register.SET_STATE, b"\x04") + _request(3, 29, b"x" * 40)
    reader = FrameReader()
    out = []
    for i in range(0, len(stream), 5):  # arrives in 5-byte pieces
        out += reader.feed(stream[i : i + 5])
    assert [(r.transaction, r.register, r.payload) for r in out] == [
        (1, 13, b""),
        (2, 12, b"\x04"),
        (3, 29, b"x" * 40),
    ]
    with pytest.raises(FramingError, match="length field"):
        FrameReader().feed(struct.pack(">HHHB", 1, 2, 0, 13))


def test_reply_and_feedback_carry_what_the_sdk_reads():
    req = Request(0x1234, 3, Register.GET_ERROR, b"")
    frame = reply(req, Status.ERROR | Status.NOT_READY, bytes([31, 0]))
    # SDK: transaction, protocol and register echoed; length = payload + 2; status byte 7 (0x40 error, 0x10 not ready)
    assert frame[:7] == struct.pack(">HHHB", 0x1234, 3, 4, 15) and frame[7] == 0x50 and frame[8:] == bytes([31, 0])
    fb = feedback(Request(7, 3, Register.FEEDBACK_CHECK, b""), kind=2, code=0)
    # SDK: register 0xFF at byte 6 routes it to the feedback queue; byte 8 the type, byte 12 the result code
    assert fb[6] == 0xFF and fb[8] == 2 and fb[12] == 0 and struct.unpack(">H", fb[4:6])[0] + 6 == len(fb)


def test_real_report_decodes_with_the_sdks_own_layout():
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6, -0.7])
    pose = [300.0, -20.0, 150.0, 3.1, 0.1, -0.2]
    frame = real_report(state=1, mode=1, cmdnum=5, q_rad=q, tcp_pose=pose, torque=[0.5] * 7)
    assert len(frame) == REPORT_BYTES
    parsed = ReportDataStructure.create(30003, is_radian=True)
    parsed.update(frame)
    assert parsed.data_size == REPORT_BYTES and parsed.state == 1 and parsed.mode == 1 and parsed.cmd_num == 5
    assert parsed.actual_joint_angle == pytest.approx(q, abs=1e-6)
    assert parsed.actual_tcp_pose == pytest.approx(pose, abs=1e-4)
    with pytest.raises(ValueError, match="7 joints"):
        real_report(0, 0, 0, q[:6], pose, [0.0] * 7)


class _Registers:
    def __init__(self) -> None:
        self.values = {0x0702: 0x0000, 0x0703: 0x0352}  # position 850 across two registers
        self.written: list[tuple[int, int]] = []

    def read_register(self, address: int) -> int:
        return self.values.get(address, 0)

    def write_register(self, address: int, value: int) -> None:
        self.written.append((address, value))


def test_gripper_registers_through_the_tool_bus():
    regs = _Registers()
    read = tool_bus.handle(bytes([9, 8, 0x03]) + struct.pack(">HH", 0x0702, 2), regs)
    # what the SDK's get_gripper_position slices: bytes 4..7 of the reply payload are the int32 position
    assert read.ok and read.payload[:4] == bytes([9, 8, 3, 4]) and struct.unpack(">i", read.payload[4:8])[0] == 850
    write = tool_bus.handle(bytes([9, 8, 0x10]) + struct.pack(">HHB", 0x0700, 2, 4) + struct.pack(">i", 425), regs)
    assert write.ok and regs.written == [(0x0700, 425)]
    assert not tool_bus.handle(bytes([9, 5, 0x03, 0, 0, 0, 1]), regs).ok  # another device on the bus: not emulated
    assert tool_bus.read_host_register(bytes([9, 0x0A, 0x0B])) == (True, struct.pack(">i", 11))
