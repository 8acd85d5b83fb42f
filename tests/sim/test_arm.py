"""The simulated xArm in servo mode: tracking, controller errors, stop, fault hooks; the gripper's SDK range."""

import time

import numpy as np
import pytest

from drivers.errors import ArmStoppedError, ControllerError, NotConnectedError
from drivers.sim import SimArm, SimGripper, SimWorld
from motion.interpolate import minimum_jerk_path

RATE = 100.0


@pytest.fixture
def world(stepped_profile):
    return SimWorld(stepped_profile.sim, stepped_profile.camera)


def stream(world, arm, path):
    """Send each set-point, advance one tick, and return the tracking error just before the next command."""
    errors = []
    for q in path:
        arm.servo(q)
        world.step(1.0 / RATE)
        errors.append(np.abs(arm.read_state().q - q).max())
    return np.array(errors)


def test_tracks_a_commanded_joint_path(world):
    with SimArm(world, RATE) as arm:
        q0 = arm.read_state().q
        target = q0 + np.array([0.5, 0.3, -0.4, 0.3, 0.6, -0.3, 1.0])
        path = minimum_jerk_path(q0, target, RATE, max_velocity=1.5)
        errors = stream(world, arm, path)
        assert errors.max() < 0.01  # within 10 mrad while moving at up to 1.5 rad/s
        world.step(0.3)
        np.testing.assert_allclose(arm.read_state().q, target, atol=2e-3)


def test_joint_limit_set_point_raises_error_23_and_holds(world):
    with SimArm(world, RATE) as arm:
        q = arm.read_state().q
        bad = q.copy()
        bad[1] = world.spec.upper[1] + 0.01
        with pytest.raises(ControllerError) as e:
            arm.servo(bad)
        assert e.value.code == 23 and "joint2" in str(e.value)
        assert arm.read_state().fault_code == 23
        world.step(0.2)
        np.testing.assert_allclose(arm.read_state().q, q, atol=1e-3)  # did not move
        with pytest.raises(ControllerError, match="uncleared"):
            arm.servo(q)
        arm.clear_fault()
        arm.servo(q)  # accepted again


def test_speed_beyond_controller_limit_raises_error_24(world):
    with SimArm(world, RATE) as arm:
        q = arm.read_state().q
        jump = q + np.array([0, 0, 0, 0, 0, 0, 0.1])  # 0.1 rad in one 10 ms tick = 10 rad/s
        with pytest.raises(ControllerError) as e:
            arm.servo(jump)
        assert e.value.code == 24 and "joint7" in str(e.value)


def test_stop_holds_and_refuses_until_cleared(world):
    with SimArm(world, RATE) as arm:
        q0 = arm.read_state().q
        path = minimum_jerk_path(q0, q0 + 0.6, RATE, max_velocity=1.5)
        stream(world, arm, path[: len(path) // 2])
        arm.stop()
        world.step(0.2)
        held = arm.read_state().q
        world.step(0.3)
        np.testing.assert_allclose(arm.read_state().q, held, atol=1e-4)
        with pytest.raises(ArmStoppedError):
            arm.servo(held)
        arm.clear_fault()
        arm.servo(held)


def test_injected_arm_error_fires_at_its_time(sim_profile_with):
    profile = sim_profile_with({"sim": {"faults": {"arm_error_at_s": 0.1, "arm_error_code": 31}}})
    world = SimWorld(profile.sim, profile.camera)
    with SimArm(world, RATE) as arm:
        q = arm.read_state().q
        arm.servo(q)
        world.step(0.05)
        assert arm.read_state().fault_code == 0
        world.step(0.1)
        assert arm.read_state().fault_code == 31
        with pytest.raises(ControllerError) as e:
            arm.servo(q)
        assert e.value.code == 31


def test_injected_stall_blocks_one_servo_call(sim_profile_with):
    profile = sim_profile_with({"sim": {"faults": {"servo_stall_at_s": 0.0, "servo_stall_s": 0.15}}})
    world = SimWorld(profile.sim, profile.camera)
    with SimArm(world, RATE) as arm:
        q = arm.read_state().q
        t0 = time.perf_counter()
        arm.servo(q)
        assert time.perf_counter() - t0 >= 0.15
        t0 = time.perf_counter()
        arm.servo(q)
        assert time.perf_counter() - t0 < 0.05


def test_non_finite_or_wrong_size_commands_are_rejected(world):
    with SimArm(world, RATE) as arm:
        with pytest.raises(ValueError, match="7 finite"):
            arm.servo(np.full(7, np.nan))
        with pytest.raises(ValueError, match="7 finite"):
            arm.servo(np.zeros(6))
    with pytest.raises(NotConnectedError):
        arm.servo(np.zeros(7))


def test_gripper_takes_the_sdk_range(world):
    with SimGripper(world) as gripper:
        gripper.set_position_sdk(425)
        world.step(1.0)
        expected = world.spec.gripper.sdk_to_width(425)
        state = gripper.read_state()
        assert state.width_m == pytest.approx(expected, abs=1e-3)
        for bad in (-1, 851, float("nan")):
            with pytest.raises(ValueError, match=r"0\.\.850"):
                gripper.set_position_sdk(bad)
        gripper.command(0.03)
        world.step(1.0)
        assert gripper.read_state().width_m == pytest.approx(0.03, abs=1.5e-3)
