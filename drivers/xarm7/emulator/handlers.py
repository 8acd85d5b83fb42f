"""One function per register: decode the arguments, act on the controller model, encode the results.

A handler returns an Answer; the server adds the controller's status byte (error, warning, not ready) and marks
the reply invalid when the handler refused the arguments. Arguments that do not decode raise ValueError, which
the server also answers as invalid.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.xarm7.emulator import tool_bus
from drivers.xarm7.emulator.controller import ControllerModel
from drivers.xarm7.emulator.wire import Register, Request, floats, int32s_le, pack_floats

TEXT_BYTES = 40  # version and serial number replies
MOTION_FINISHED = 2  # feedback type: queued motion finished (servo mode queues nothing)
ALL_JOINTS = 8


@dataclass(frozen=True)
class Answer:
    payload: bytes = b""
    valid: bool = True
    feedback_kind: int | None = None  # send a feedback frame of this kind after the reply


Handler = Callable[[ControllerModel, Request], Answer]


def _text(value: str) -> Answer:
    raw = value.encode("ascii")[: TEXT_BYTES - 1]
    return Answer(raw + b"\0" * (TEXT_BYTES - len(raw)))


def _byte(request: Request, index: int = 0) -> int:
    if len(request.payload) <= index:
        raise ValueError(f"register {request.register}: missing argument byte {index}")
    return request.payload[index]


def _flag_setter(name: str) -> Handler:
    def handle(model: ControllerModel, request: Request) -> Answer:
        with model.lock:
            setattr(model.settings, name, bool(_byte(request)))
        return Answer()

    return handle


def _motion_enable(model: ControllerModel, request: Request) -> Answer:
    if _byte(request, 0) != ALL_JOINTS:  # the driver enables all joints at once; single joints are not emulated
        return Answer(valid=False)
    model.motion_enable(bool(_byte(request, 1)))
    return Answer()


def _servo_j(model: ControllerModel, request: Request) -> Answer:
    values = floats(request.payload, 10)  # 7 joints [rad], then speed, acceleration, time (ignored in servo mode)
    q = np.asarray(values[:7], dtype=np.float64)
    if not np.all(np.isfinite(q)):
        return Answer(valid=False)
    model.servo_j(q)
    return Answer()


def _set_collision_sensitivity(model: ControllerModel, request: Request) -> Answer:
    value = _byte(request)
    if not 0 <= value <= 5:
        return Answer(valid=False)
    with model.lock:
        model.settings.collision_sensitivity = value
    return Answer()


def _set_collision_tool(model: ControllerModel, request: Request) -> Answer:
    with model.lock:
        model.settings.collision_tool = request.payload[-1] if len(request.payload) > 1 else _byte(request)
    return Answer()


def _set_tcp_offset(model: ControllerModel, request: Request) -> Answer:
    offset = floats(request.payload, 6)
    with model.lock:
        model.settings.tcp_offset = tuple(offset)
    return Answer()


def _set_payload(model: ControllerModel, request: Request) -> Answer:
    mass, *cog = floats(request.payload, 4)
    if not 0.0 <= mass <= 5.0:
        return Answer(valid=False)
    with model.lock:
        model.settings.payload_kg, model.settings.payload_cog_mm = mass, tuple(cog)
    return Answer()


def _set_reduced_tcp_speed(model: ControllerModel, request: Request) -> Answer:
    (speed,) = floats(request.payload, 1)
    with model.lock:
        model.settings.reduced_tcp_speed_mm_s = speed
    return Answer()


def _set_reduced_joint_speed(model: ControllerModel, request: Request) -> Answer:
    (speed,) = floats(request.payload, 1)
    if not 0.0 < speed <= 4.0:
        return Answer(valid=False)
    with model.lock:
        model.settings.reduced_joint_speed_rad_s = speed
    return Answer()


def _set_tcp_boundary(model: ControllerModel, request: Request) -> Answer:
    x_max, x_min, y_max, y_min, z_max, z_min = int32s_le(request.payload, 6)
    if x_max < x_min or y_max < y_min or z_max < z_min:
        return Answer(valid=False)
    with model.lock:
        model.settings.tcp_boundary_mm = (x_max, x_min, y_max, y_min, z_max, z_min)
    return Answer()


def _get_reduced_state(model: ControllerModel, request: Request) -> Answer:
    spec = model.world.spec
    with model.lock:
        s = model.settings
        out = bytes([int(s.reduced_mode)])
        out += struct.pack(">6h", *(int(v) for v in s.tcp_boundary_mm))
        out += pack_floats([s.reduced_tcp_speed_mm_s, s.reduced_joint_speed_rad_s])
        out += pack_floats([v for pair in zip(spec.lower, spec.upper, strict=True) for v in pair])
        out += bytes([int(s.fence), int(s.collision_rebound)])
    return Answer(out)


def _set_state(model: ControllerModel, request: Request) -> Answer:
    return Answer(valid=model.set_state(_byte(request)))


def _set_mode(model: ControllerModel, request: Request) -> Answer:
    return Answer(valid=model.set_mode(_byte(request)))


def _get_error(model: ControllerModel, request: Request) -> Answer:
    with model.lock:
        return Answer(bytes([model.error, model.warning]))


def _get_joints(model: ControllerModel, request: Request) -> Answer:
    return Answer(pack_floats(model.report()[3]))


def _get_tcp_pose(model: ControllerModel, request: Request) -> Answer:
    return Answer(pack_floats(model.tcp_pose()))


def _tool_rs485(model: ControllerModel, request: Request) -> Answer:
    with model.lock:
        result = tool_bus.handle(request.payload, model.gripper)
    return Answer(result.payload, result.ok)


def _tool_read16(model: ControllerModel, request: Request) -> Answer:
    ok, payload = tool_bus.read_host_register(request.payload)
    return Answer(payload, ok)


def _simple(action: Callable[[ControllerModel], object]) -> Handler:
    def handle(model: ControllerModel, request: Request) -> Answer:
        action(model)
        return Answer()

    return handle


HANDLERS: dict[int, Handler] = {
    Register.GET_VERSION: lambda m, r: _text(m.version),
    Register.GET_ROBOT_SN: lambda m, r: _text(m.version.split(",")[2]),
    Register.MOTION_ENABLE: _motion_enable,
    Register.SET_STATE: _set_state,
    Register.GET_STATE: lambda m, r: Answer(bytes([m.report_state()])),
    Register.GET_CMDNUM: lambda m, r: Answer(struct.pack(">H", m.cmdnum)),
    Register.GET_ERROR: _get_error,
    Register.CLEAN_ERROR: _simple(ControllerModel.clean_error),
    Register.CLEAN_WARN: _simple(ControllerModel.clean_warn),
    Register.SET_MODE: _set_mode,
    Register.SERVO_J: _servo_j,
    Register.SET_TCP_OFFSET: _set_tcp_offset,
    Register.SET_PAYLOAD: _set_payload,
    Register.SET_COLLISION_SENSITIVITY: _set_collision_sensitivity,
    Register.GET_TCP_POSE: _get_tcp_pose,
    Register.GET_JOINTS: _get_joints,
    Register.SET_REDUCED_TCP_SPEED: _set_reduced_tcp_speed,
    Register.SET_REDUCED_JOINT_SPEED: _set_reduced_joint_speed,
    Register.GET_REDUCED_MODE: lambda m, r: Answer(bytes([int(m.settings.reduced_mode)])),
    Register.SET_REDUCED_MODE: _flag_setter("reduced_mode"),
    Register.SET_TCP_BOUNDARY: _set_tcp_boundary,
    Register.GET_REDUCED_STATE: _get_reduced_state,
    Register.SET_FENCE: _flag_setter("fence"),
    Register.SET_COLLISION_REBOUND: _flag_setter("collision_rebound"),
    Register.SET_SELF_COLLISION: _flag_setter("self_collision"),
    Register.SET_COLLISION_TOOL: _set_collision_tool,
    Register.TOOL_RS485: _tool_rs485,
    Register.TOOL_READ16: _tool_read16,
    Register.FEEDBACK_CHECK: lambda m, r: Answer(feedback_kind=MOTION_FINISHED),
    Register.SET_FEEDBACK_TYPE: lambda m, r: Answer(),
}
