"""XArm7 / XArmGripper against the fake XArmAPI: sequences, units, error mapping, stop, close, rollback."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from fake_xarm import FakeXArmAPI

from drivers.config import RobotConfig
from drivers.errors import (
    ApiError,
    ArmStoppedError,
    ControllerError,
    DeviceNotFoundError,
    NotConnectedError,
)
from drivers.xarm7 import XArm7, XArmGripper
from drivers.xarm7.controller_safety import verify
from safety.config import BoxRegion, SafetyConfig

ENABLE = ["clean_error", "clean_warn", "motion_enable", "set_mode", "set_state"]


@pytest.fixture
def fakes() -> list[FakeXArmAPI]:
    return []


def make_arm(fakes: list[FakeXArmAPI], setup=None, **safety) -> XArm7:
    def factory(ip, **kwargs):
        api = FakeXArmAPI(ip, **kwargs)
        if setup:
            setup(api)
        fakes.append(api)
        return api

    robot = RobotConfig(kind="xarm7", ip="192.168.1.208", collision_sensitivity=4, payload_kg=0.9)
    cfg = SafetyConfig(
        max_joint_velocity_rad_s=1.0,
        max_tcp_speed_m_s=0.25,
        workspace=BoxRegion(min_m=(-0.3, -0.6, 0.0), max_m=(0.9, 0.6, 1.1)),
        **safety,
    )
    return XArm7(robot, cfg, api_factory=factory)


def test_connect_uses_real_report_and_runs_the_enable_sequence(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    assert api.init == {"port": "192.168.1.208", "is_radian": False, "do_not_open": True, "report_type": "real"}
    names = api.names()
    assert names[:4] == ["connect", "register_report_callback", "get_version", *ENABLE[:1]]
    # enable in mode 0, configure safety, then the same sequence into servo mode
    first = names.index("clean_error")
    assert names[first : first + 5] == ENABLE
    last = len(names) - 1 - names[::-1].index("clean_error")
    assert names[last : last + 5] == ENABLE and last > names.index("set_fence_mode")
    assert api.mode == 1 and api.state == 2
    assert arm.firmware_version == "v2.6.0"


def test_controller_safety_written_in_sdk_units(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    args = {name: (a, k) for name, a, k in api.calls}
    assert args["set_reduced_tcp_boundary"][0][0] == pytest.approx([900, -300, 600, -600, 1100, 0])
    assert args["set_reduced_max_joint_speed"][0][0] == pytest.approx(math.degrees(1.0))
    assert args["set_reduced_max_joint_speed"][1] == {"is_radian": False}
    assert args["set_reduced_max_tcp_speed"][0][0] == pytest.approx(250.0)
    assert args["set_tcp_offset"][0][0] == pytest.approx([0, 0, 172, 0, 0, 0])
    assert args["set_tcp_load"][0] == (0.9, [0.0, 0.0, 48.0])
    assert args["set_collision_sensitivity"][0] == (4,)
    assert args["set_reduced_mode"][0] == (True,) and args["set_fence_mode"][0] == (True,)
    assert verify(api, arm.controller_safety) == []
    api.reduced[5] = 0
    api.reduced[3] = 180.0
    problems = verify(api, arm.controller_safety)
    assert any("fence" in p for p in problems) and any("joint speed" in p for p in problems)


def test_servo_converts_radians_to_degrees_and_state_back(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    q = np.radians(api.angles) + np.array([0.01, -0.02, 0.0, 0.03, 0.0, -0.01, 0.02])
    arm.servo(q)
    name, args, kwargs = api.calls[-1]
    assert name == "set_servo_angle_j" and kwargs == {"is_radian": False}
    assert args[0] == pytest.approx(np.degrees(q).tolist())
    on_report = api.report_callbacks.pop()  # the test delivers the reports from here on
    assert api.wait_reports(1)  # a report pass that started before the pop has finished
    step = np.full(7, math.radians(0.1))
    on_report({"joints": np.degrees(q).tolist(), "state": 1})
    on_report({"joints": np.degrees(q + step).tolist(), "state": 1})
    state = arm.read_state()
    # no speeds in the 'real' report: the change between two reports over the controller's 10 ms report period
    assert state.q == pytest.approx(q) and state.qd == pytest.approx(step / 0.01)
    assert state.fault_code == 0


@pytest.mark.parametrize("bad", [np.full(7, np.nan), np.zeros(6)])
def test_servo_rejects_malformed_set_points(fakes, bad):
    arm = make_arm(fakes)
    arm.connect()
    with pytest.raises(ValueError, match="7 finite"):
        arm.servo(bad)
    assert "set_servo_angle_j" not in fakes[0].names()


def test_controller_error_maps_to_typed_error_and_clear_fault_recovers(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    api.raise_error(31)
    with pytest.raises(ControllerError, match="collision") as info:
        arm.servo(np.zeros(7))
    assert info.value.code == 31
    assert arm.read_state().fault_code == 31
    arm.clear_fault()
    assert api.error_code == 0 and api.mode == 1 and api.state == 2
    arm.servo(np.zeros(7))


def test_api_code_1_reads_the_controller_error(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    api.codes["set_servo_angle_j"].append(1)
    api.error_code = 0
    api.codes["get_err_warn_code"] = []
    # the controller raised error 35 between the report and the call
    original = api.get_err_warn_code
    api.get_err_warn_code = lambda show=False: (original()[0], [35, 0])
    with pytest.raises(ControllerError, match="safety boundary") as info:
        arm.servo(np.zeros(7))
    assert info.value.code == 35


def test_estop_button_held_makes_clear_fault_fail_readably(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    api.estop_pressed = True
    api.raise_error(1)
    with pytest.raises(ControllerError, match="emergency stop button"):
        arm.clear_fault()


@pytest.mark.parametrize(
    ("code", "error", "text"), [(3, ApiError, "reply timeout"), (-9, ArmStoppedError, "emergency")]
)
def test_servo_api_codes(fakes, code, error, text):
    arm = make_arm(fakes)
    arm.connect()
    fakes[0].codes["set_servo_angle_j"].append(code)
    with pytest.raises(error, match=text):
        arm.servo(np.zeros(7))


def test_warning_is_cleared_not_raised(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    api.warn_code = 11
    api.codes["set_servo_angle_j"].append(2)
    arm.servo(np.zeros(7))
    assert api.names()[-1] == "clean_warn" and api.warn_code == 0


def test_stop_latches_until_clear_fault(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    arm.stop()
    assert api.calls[-1][:2] == ("set_state", (4,)) and api.state == 4
    with pytest.raises(ArmStoppedError):
        arm.servo(np.zeros(7))
    arm.clear_fault()
    arm.servo(np.zeros(7))
    arm.emergency_stop()
    assert "emergency_stop" in api.names()
    with pytest.raises(ArmStoppedError):
        arm.servo(np.zeros(7))


def test_stop_from_another_thread_during_a_stalled_servo_call(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    release = threading.Event()
    api.stalls["set_servo_angle_j"] = release
    errors: list[BaseException] = []

    def stream():
        try:
            arm.servo(np.zeros(7))
        except BaseException as e:
            errors.append(e)

    t = threading.Thread(target=stream)
    t.start()
    assert api.stall_started.wait(2)
    t0 = time.perf_counter()
    arm.stop()  # must not wait for the stalled call
    assert time.perf_counter() - t0 < 0.1
    assert ("set_state", (4,), {}) in api.calls
    release.set()
    t.join(2)
    assert len(errors) == 1 and isinstance(errors[0], ArmStoppedError)
    assert arm.last_servo_call_s > 0


def test_dropped_link_is_a_readable_error_and_close_still_tries_everything(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    api.drop_link()
    with pytest.raises(NotConnectedError, match=r"connection to 192\.168\.1\.208 lost"):
        arm.read_state()
    with pytest.raises(NotConnectedError):
        arm.servo(np.zeros(7))
    arm.close()
    tail = api.names()[-5:]
    assert tail == ["set_state", "release_report_callback", "set_mode", "set_state", "disconnect"]
    arm.close()  # idempotent
    assert api.names()[-5:] == tail


def test_close_leaves_servo_mode(fakes):
    arm = make_arm(fakes)
    with arm:
        arm.servo(np.zeros(7))
    api = fakes[0]
    assert [c[:2] for c in api.calls[-3:]] == [("set_mode", (0,)), ("set_state", (0,)), ("disconnect", ())]
    assert api.calls[-5][:2] == ("set_state", (4,)) and api.calls[-4][0] == "release_report_callback"
    assert not arm.is_connected and api.mode == 0
    with pytest.raises(NotConnectedError):
        arm.read_state()


def test_close_on_exception_inside_the_context(fakes):
    arm = make_arm(fakes)
    with pytest.raises(RuntimeError, match="boom"), arm:
        raise RuntimeError("boom")
    assert fakes[0].names()[-1] == "disconnect" and fakes[0].mode == 0


def test_unreachable_controller(fakes):
    arm = make_arm(fakes, setup=lambda api: setattr(api, "refuse_connect", True))
    with pytest.raises(DeviceNotFoundError, match=r"ping 192\.168\.1\.208"):
        arm.connect()
    assert not arm.is_connected


def test_connect_rolls_back_when_a_safety_setting_fails(fakes):
    arm = make_arm(fakes, setup=lambda api: api.codes["set_fence_mode"].append(-8))
    with pytest.raises(ApiError, match="set_fence_mode returned API code -8: out of range"):
        arm.connect()
    api = fakes[0]
    assert not arm.is_connected and not api.connected
    assert "set_servo_angle_j" not in api.names() and api.names()[-1] == "disconnect"
    assert api.mode == 0


def test_gripper_metres_to_sdk_and_back(fakes):
    arm = make_arm(fakes)
    gripper = XArmGripper(arm)
    with pytest.raises(NotConnectedError, match="connect the XArm7 first"):
        gripper.connect()
    arm.connect()
    gripper.connect()
    api = fakes[0]
    assert {"set_gripper_mode", "set_gripper_enable", "set_gripper_speed"} <= set(api.names())
    spec = arm.spec.gripper
    gripper.command(0.04)
    pos = api.calls[-1][1][0]
    assert pos == round(spec.width_to_sdk(0.04)) and 0 < pos < 850
    state = gripper.read_state()
    assert state.width_m == pytest.approx(0.04, abs=0.001)
    gripper.command(spec.max_width_m)
    assert api.gripper_position == 850
    with pytest.raises(ValueError, match="outside the stroke"):
        gripper.command(0.2)
    gripper.stop()
    assert api.calls[-1][:2] == ("set_gripper_position", (850,))
    arm.close()
    assert not gripper.is_connected


def test_servo_refuses_a_jump_larger_than_the_per_tick_limit(fakes):
    arm = make_arm(fakes)  # safety.max_joint_step_rad 0.04 -> the driver refuses steps above 0.06 rad
    arm.connect()
    api = fakes[0]
    q0 = np.radians(api.angles)
    arm.servo(q0 + 0.05)
    with pytest.raises(ValueError, match=r"joint1 set-point jumps 0\.1000 rad .* refused"):
        arm.servo(q0 + 0.15)
    assert api.names().count("set_servo_angle_j") == 1
    with pytest.raises(ValueError, match="jumps"):  # after a fault the reference is the measured position again
        arm.clear_fault()
        arm.servo(q0 + 0.2)


def test_state_stamp_is_the_report_time_so_a_silent_report_link_shows(fakes):
    arm = make_arm(fakes)
    arm.connect()
    api = fakes[0]
    assert api.wait_reports(3)
    first = arm.read_state().stamp_s
    assert api.wait_reports(2)
    assert arm.read_state().stamp_s > first and arm.report_count >= 5
    api.report_hz = 0  # the report socket goes quiet while commands still work
    assert api.wait_reports(2)  # (a report under way when it went quiet has arrived)
    frozen = arm.read_state().stamp_s
    assert api.wait_reports(3)
    assert arm.read_state().stamp_s == frozen
