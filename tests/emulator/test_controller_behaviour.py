"""What the emulated controller does with what it receives, as the real one does (hardware-notes.md): errors 23
(joint limit), 24 (speed), 35 (fence), 31 (collision), the software stop and the e-stop button (state 4), errors
that hold until clean_error, and servo mode's latest set-point winning. Through the real SDK; the driver where it
can reach the case, a bare XArmAPI (its own joint-range check off) where the driver refuses first."""

from __future__ import annotations

import contextlib
import io

import numpy as np
import pytest
from emulator_helpers import make_arm, wait_for, world_q, world_qd

from drivers.errors import ArmStoppedError, ControllerError
from safety.config import BoxRegion, SafetyConfig

with contextlib.redirect_stdout(io.StringIO()):
    from xarm.wrapper import XArmAPI


@contextlib.contextmanager
def bare_sdk(emulator):
    """An SDK client in servo mode without the SDK's own joint-range check (radians)."""
    api = XArmAPI(emulator.address, is_radian=True, report_type="real", check_joint_limit=False, forbid_uds=True)
    try:
        api.clean_error()
        api.motion_enable(True)
        api.set_mode(1)
        api.set_state(0)
        assert wait_for(lambda: api.mode == 1 and api.state in (0, 1, 2))
        yield api
    finally:
        api.disconnect()


def holds(world, q: np.ndarray) -> bool:
    """At rest next to q (a stop holds where the arm is, a tick or two short of the last set-point)."""
    return np.abs(world_q(world) - q).max() < 0.02 and np.abs(world_qd(world)).max() < 0.01


def test_joint_limit_and_speed_errors_hold_until_clean_error(emulator, world):
    with bare_sdk(emulator) as api:
        q0 = world_q(world)
        over = q0.copy()
        over[3] = world.spec.upper[3] + 0.05
        assert api.set_servo_angle_j(over.tolist()) == 1  # the controller judges it; its reply carries the error
        assert wait_for(lambda: api.state == 4)
        assert api.get_err_warn_code() == (0, [23, 0]) and api.mode == 0
        assert api.set_servo_angle_j(q0.tolist()) == 1  # error held: refused, nothing executed
        assert [s.accepted for s in emulator.journal.setpoints] == [False, False]
        assert wait_for(lambda: holds(world, q0))
        api.clean_error()
        assert api.get_err_warn_code()[1] == [0, 0]
        assert api.set_servo_angle_j(q0.tolist()) == 9  # cleared but stopped: not ready until enabled again
        api.motion_enable(True)
        api.set_mode(1)
        api.set_state(0)
        assert wait_for(lambda: api.mode == 1 and api.state in (0, 1, 2))
        assert api.set_servo_angle_j((q0 + 0.002).tolist()) == 0 and emulator.journal.setpoints[-1].accepted
        jump = q0 + np.array([0.2, 0, 0, 0, 0, 0, 0])  # 0.2 rad in one 10 ms tick: 20 rad/s
        api.set_servo_angle_j(jump.tolist())
        assert wait_for(lambda: api.get_err_warn_code()[1][0] == 24)
        assert "rad/s" in emulator.journal.errors[-1][2]
        assert wait_for(lambda: holds(world, q0 + 0.002))


def test_a_cleaned_error_the_twin_raised_does_not_come_back_on_the_next_tick(emulator, world):
    """The controller's cycle re-reads the twin's fault: cleaning the error must acknowledge it there too."""
    with bare_sdk(emulator) as api:
        over = world_q(world)
        over[3] = world.spec.upper[3] + 0.05
        api.set_servo_angle_j(over.tolist())
        assert wait_for(lambda: api.get_err_warn_code()[1][0] == 23)
        api.clean_error()
        emulator.model.tick()  # a cycle between clean_error and set_state(0)
        assert emulator.model.error == 0 and api.get_err_warn_code()[1] == [0, 0]
        assert emulator.model.set_state(0) and emulator.model.state == 2  # ready: nothing raised it again


def test_reduced_mode_lowers_the_speed_limit(emulator, world):
    with bare_sdk(emulator) as api:
        api.set_reduced_max_joint_speed(0.5)  # rad/s (is_radian)
        api.set_reduced_mode(True)
        api.set_state(0)
        q = world_q(world)
        for _ in range(5):  # 1 rad/s: fine for the vendor limit, twice the reduced one
            q = q + np.array([0.01, 0, 0, 0, 0, 0, 0])
            api.set_servo_angle_j(q.tolist())
            if api.state == 4:
                break
        assert wait_for(lambda: api.get_err_warn_code()[1][0] == 24)


def test_leaving_the_fence_raises_35_and_the_arm_holds_inside(emulator, world, robot_model):
    q0 = world_q(world)
    tcp = robot_model.tcp_pose(q0)[:3, 3]
    box = BoxRegion(name="workspace", min_m=(-0.35, -0.7, -0.005), max_m=(tcp[0] + 0.01, 0.7, 1.2))
    fence = SafetyConfig(workspace=box)
    with make_arm(emulator, fence) as arm:
        dq = np.linalg.pinv(robot_model.jacobian(q0)[:3]) @ np.array([0.002, 0.0, 0.0])  # 2 mm of +x per set-point
        q = arm.read_state().q
        with pytest.raises(ControllerError, match="controller error 35"):
            for _ in range(30):
                q = q + dq
                arm.servo(q)
        accepted = emulator.journal.accepted()
        assert accepted and all(robot_model.tcp_pose(s.q_rad)[0, 3] <= tcp[0] + 0.01 for s in accepted)
        assert not emulator.journal.setpoints[-1].accepted
        assert arm.read_state().fault_code == 35  # the report shows state 4; the driver asks why
        assert wait_for(lambda: holds(world, accepted[-1].q_rad))
        arm.clear_fault()  # cleared: back inside, servo mode again
        arm.servo(accepted[-1].q_rad)
        assert emulator.journal.setpoints[-1].accepted


def test_pressing_into_the_table_raises_31(emulator, world, robot_model):
    low = SafetyConfig(workspace=BoxRegion(name="workspace", min_m=(-0.35, -0.7, -0.3), max_m=(0.95, 0.7, 1.2)))
    with make_arm(emulator, low) as arm:
        q = arm.read_state().q
        with pytest.raises(ControllerError, match="controller error 31"):
            for _ in range(400):  # down 2 mm per set-point: through the table top (z = 0) if nothing stops it
                q = q + np.linalg.pinv(robot_model.jacobian(q)[:3]) @ np.array([0.0, 0.0, -0.002])
                arm.servo(q)
                stamp = arm.report_count
                wait_for(lambda: arm.report_count > stamp)  # noqa: B023 - one set-point per report
        assert emulator.journal.errors[-1][1] == 31 and "by contact" in emulator.journal.errors[-1][2]
        assert robot_model.tcp_pose(emulator.journal.accepted()[-1].q_rad)[2, 3] < 0.02  # it was at the table


def test_stop_and_the_estop_button_put_the_controller_in_state_4(emulator, arm, world):
    q0 = arm.read_state().q
    arm.emergency_stop()  # the SDK repeats set_state(4) until the report says 4
    assert arm.api.state == 4 and emulator.journal.stops
    with pytest.raises(ArmStoppedError):
        arm.servo(q0)
    arm.clear_fault()
    arm.servo(q0 + 0.001)
    assert emulator.journal.setpoints[-1].accepted
    emulator.press_estop_button()
    assert wait_for(lambda: arm.read_state().fault_code == 1)  # seen in the report's state 4, code asked for
    with pytest.raises(ControllerError, match="controller error 1"):
        arm.clear_fault()  # the button is still pressed: error 1 comes back
    emulator.release_estop_button()
    arm.clear_fault()
    assert arm.read_state().fault_code == 0


def test_the_latest_set_point_wins(emulator, arm, world):
    q0 = arm.read_state().q
    first, latest = q0 + 0.01, q0 - 0.01
    arm.servo(q0 + 0.005)
    arm.servo(first)
    arm.servo(latest)  # back-to-back: servo mode executes each at once, the last one is where the arm goes
    assert wait_for(lambda: np.abs(world_q(world) - latest).max() < 1e-3)
    assert wait_for(lambda: holds(world, latest))
