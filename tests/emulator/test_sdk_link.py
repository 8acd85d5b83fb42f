"""The real driver through the real xarm-python-sdk over TCP to the emulator: the connect handshake, what the
controller is told (in its units), unit conversions both ways, the jump refusal, the gripper, and connect/close
being atomic and idempotent over real sockets."""

from __future__ import annotations

import ipaddress
import math

import numpy as np
import pytest
from emulator_helpers import make_arm, wait_for, world_q

from drivers.errors import ControllerError, DeviceNotFoundError
from drivers.xarm7.controller_safety import verify
from drivers.xarm7.emulator.wire import Register
from safety.config import SafetyConfig

STRICT = SafetyConfig(max_joint_velocity_rad_s=1.0, max_tcp_speed_m_s=0.25)


def registers(emulator) -> list[int]:
    return [r for _, r in emulator.server.requests]


def test_connect_writes_the_profiles_safety_in_controller_units(emulator, robot_model):
    arm = make_arm(emulator, STRICT, collision_sensitivity=4, payload_kg=0.9)
    with arm:
        s, model = emulator.model.settings, emulator.model
        assert "v2.7.1" in arm.firmware_version and arm.report_count > 0
        assert model.mode == 1 and model.report_state() in (1, 2) and model.enabled
        assert s.tcp_offset == pytest.approx((0, 0, 172, 0, 0, 0))  # mm and rad, as the controller takes it
        lo, hi = np.array(STRICT.workspace.min_m) * 1000, np.array(STRICT.workspace.max_m) * 1000
        assert s.tcp_boundary_mm == pytest.approx((hi[0], lo[0], hi[1], lo[1], hi[2], lo[2]), abs=1.0)
        assert s.reduced_joint_speed_rad_s == pytest.approx(1.0, rel=1e-6)  # the SDK sends rad/s on the wire
        assert s.reduced_tcp_speed_mm_s == pytest.approx(250.0)
        assert s.reduced_mode and s.fence and s.self_collision and s.collision_tool == 1
        assert s.collision_sensitivity == 4 and s.payload_kg == pytest.approx(0.9)
        assert s.payload_cog_mm == pytest.approx((0, 0, 48))
        assert emulator.server.unknown == []  # every register the SDK used is emulated
        assert verify(arm.api, arm.controller_safety, lambda q: robot_model.tcp_pose(q)[:3, 3]) == []
        # the TCP check sees the offset's effect: a controller told another offset reports another TCP
        with model.lock:
            s.tcp_offset = (0.0, 0.0, 0.172, 0.0, 0.0, 0.0)  # metres where mm were due
        stamp = arm.report_count
        assert wait_for(lambda: arm.report_count > stamp + 2)
        problems = verify(arm.api, arm.controller_safety, lambda q: robot_model.tcp_pose(q)[:3, 3])
        assert len(problems) == 1 and "172" in problems[0] and "not applied" in problems[0]


def test_set_points_arrive_in_radians_and_state_comes_back_in_si(emulator, arm, world):
    q0 = arm.read_state().q
    np.testing.assert_allclose(q0, world_q(world), atol=1e-5)  # float32 degrees on the wire
    step = np.array([0.01, -0.01, 0.005, 0.01, -0.005, 0.01, 0.02])
    targets = [q0 + k * step / 4 for k in range(1, 41)]
    for q in targets:
        arm.servo(q)
    received = [s.q_rad for s in emulator.journal.accepted()]
    np.testing.assert_allclose(received[-40:], targets, atol=2e-6)
    assert wait_for(lambda: np.abs(arm.read_state().q - targets[-1]).max() < 2e-3)
    # joint speeds come from the report's change over its period: a joint moved at a known rate shows it
    rate = np.array([0.2, 0.0, 0.0, 0.0, 0.0, 0.0, -0.2])  # rad/s
    q, seen = targets[-1], []
    for _ in range(60):
        stamp = arm.report_count
        q = q + rate * 0.01
        arm.servo(q)
        wait_for(lambda: arm.report_count > stamp)  # noqa: B023 - one set-point per report
        seen.append(arm.read_state().qd)
    assert np.median(np.array(seen)[20:], axis=0) == pytest.approx(rate, abs=0.05)


def test_a_jump_is_refused_before_the_sdk_and_nothing_reaches_the_controller(emulator, arm):
    q0 = arm.read_state().q
    before = len(emulator.journal.setpoints)
    with pytest.raises(ValueError, match=r"jumps .* refused"):
        arm.servo(q0 + np.array([0.0, 0.0, 0.0, 0.2, 0.0, 0.0, 0.0]))
    assert len(emulator.journal.setpoints) == before
    # past a joint limit the SDK itself refuses (API code -8, its own range table) before anything is sent
    over = q0.copy()
    over[3] = arm.spec.upper[3] + 0.01
    assert arm.api.set_servo_angle_j(np.degrees(over).tolist(), is_radian=False) == -8
    assert len(emulator.journal.setpoints) == before


def test_gripper_positions_in_sdk_units_and_widths_back_in_metres(emulator, arm, gripper, world):
    spec = world.spec.gripper
    gripper.command(0.03)
    assert emulator.model.gripper.commands[-1] == round(spec.width_to_sdk(0.03))
    assert emulator.model.gripper.enabled and emulator.model.gripper.speed == arm.config.gripper_speed
    assert wait_for(lambda: abs(gripper.read_state().width_m - 0.03) < 1e-3, timeout_s=5.0)
    gripper.command(spec.max_width_m)
    assert emulator.model.gripper.commands[-1] == spec.sdk_open
    assert wait_for(lambda: abs(gripper.read_state().width_m - spec.max_width_m) < 1e-3, timeout_s=5.0)


def test_a_refused_connection_leaves_nothing_open(emulator, safety):
    emulator.refuse_connections()
    arm = make_arm(emulator, safety)
    with pytest.raises(DeviceNotFoundError, match="no xArm controller answers"):
        arm.connect()
    assert arm.api is None and not arm.is_connected and not emulator.server.requests
    arm.close()  # nothing to release, no error
    emulator.accept_connections()
    with arm:
        assert arm.is_connected
    assert not arm.is_connected


def test_a_connect_that_fails_halfway_releases_the_link_and_a_retry_works(emulator, safety):
    emulator.press_estop_button()  # the enable sequence cannot complete: error 1 holds
    arm = make_arm(emulator, safety)
    with pytest.raises(ControllerError, match="controller error 1"):
        arm.connect()
    assert arm.api is None
    assert wait_for(lambda: emulator.server.connections["command"] == 1 and not emulator.server._command_links)
    emulator.release_estop_button()
    arm.connect()
    arm.connect()  # idempotent: still the one link
    assert emulator.server.connections["command"] == 2 and len(emulator.server._command_links) == 1
    arm.close()
    stops = len(emulator.journal.stops)
    arm.close()  # idempotent: nothing more is sent
    assert len(emulator.journal.stops) == stops >= 1
    assert wait_for(lambda: not emulator.server._command_links and not emulator.server._report_links)
    assert registers(emulator)[-1] != Register.SERVO_J and emulator.model.mode == 0  # close left servo mode


def test_the_commands_travel_on_port_502_of_the_emulators_address(emulator, arm):
    (peer,) = [s.getpeername() for s in emulator.server._command_links]
    (local,) = [s.getsockname() for s in emulator.server._command_links]
    assert local == (emulator.address, 502) and ipaddress.ip_address(peer[0]).is_loopback
    assert arm.api._arm._stream.com.getpeername() == (emulator.address, 502)
    assert arm.api._arm._stream_report.com.getpeername() == (emulator.address, 30003)
    assert math.isfinite(arm.read_state().q.sum())
