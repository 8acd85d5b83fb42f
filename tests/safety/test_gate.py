"""The gate catches a crafted trajectory for every violation kind, reports times and names, and passes a
valid one."""

from __future__ import annotations

import numpy as np
import pytest
from trajectories import RATE_HZ, min_jerk, trajectory

from safety.collision import CollisionWorld
from safety.config import BoxRegion, SafetyConfig
from safety.gate import TrajectoryError, check_configuration, subsample, validate
from safety.geometry import WORLD, Primitive, pose
from safety.trajectory import GripperEvent, JointTrajectory

DT = 1.0 / RATE_HZ


@pytest.fixture(scope="module")
def world(robot) -> CollisionWorld:
    return CollisionWorld(robot)


def _home_move(robot, delta, duration_s=2.0) -> np.ndarray:
    return min_jerk(robot.home_q, robot.home_q + np.asarray(delta), duration_s)


def _of_kind(report, kind):
    return [v for v in report.violations if v.kind == kind]


def test_valid_trajectory_passes(robot, world):
    report = validate(trajectory(_home_move(robot, [0.3, 0.1, -0.2, 0.2, 0.1, -0.1, 0.5])), world)
    assert report.ok, report.reason()
    assert report.to_dict()["ok"] is True and report.to_dict()["violations"] == []
    assert report.configurations_checked >= report.samples


def test_joint_limit(robot, world):
    upper2 = robot.upper[1] - world.config.joint_margin_rad
    q1 = robot.home_q.copy()
    q1[1] = upper2 + 0.02  # within the vendor range but inside the safety margin
    report = validate(trajectory(min_jerk(robot.home_q, q1, 6.0)), world)
    hits = _of_kind(report, "joint_limit")
    assert hits and all(v.names == ("joint2",) and v.value > upper2 for v in hits)
    assert hits[-1].time_s == pytest.approx(6.0)
    assert hits[0].limit == pytest.approx(upper2)


def test_velocity(robot, world):
    t = np.arange(0, 0.3, DT)
    q = np.tile(robot.home_q, (len(t), 1))
    q[:, 0] += 3.3 * t  # 3.3 rad/s > 180 deg/s
    hits = _of_kind(validate(trajectory(q), world), "velocity")
    assert hits and {v.names for v in hits} == {("joint1",)}
    assert max(abs(v.value) for v in hits) == pytest.approx(3.3, rel=1e-6)


def test_acceleration_with_stricter_profile(robot):
    strict = CollisionWorld(robot, SafetyConfig(max_joint_acceleration_rad_s2=2.0))
    q = _home_move(robot, [0.5, 0, 0, 0, 0, 0, 0], duration_s=1.0)  # peak 5.77 * 0.5 / 1 = 2.9 rad/s^2
    report = validate(trajectory(q), strict)
    assert _of_kind(report, "acceleration") and not _of_kind(report, "velocity")
    assert validate(trajectory(q), CollisionWorld(robot)).ok  # within the vendor's 1146 deg/s^2


def test_jerk(robot, world):
    t = np.arange(0, 0.2, DT)
    q = np.tile(robot.home_q, (len(t), 1))
    q[:, 6] += 0.5 * 10.0 * t**2  # 10 rad/s^2 from rest at once: jerk 10 / dt = 2500 rad/s^3
    report = validate(trajectory(q), world)
    jerks = _of_kind(report, "jerk")
    assert jerks and jerks[0].time_s == pytest.approx(DT) and jerks[0].names == ("joint7",)
    # ending at 2 rad/s means an instant stop after the last sample: reported as such
    assert any("stopping after the last sample" in v.detail for v in report.violations)


def test_step(robot, world):
    q = np.tile(robot.home_q, (50, 1))
    q[25:, 2] += 0.05  # one 0.05 rad jump > 0.04 rad per tick
    hits = _of_kind(validate(trajectory(q), world), "step")
    assert len(hits) == 1 and hits[0].time_s == pytest.approx(25 * DT) and hits[0].names == ("joint3",)
    report = validate(trajectory(np.tile(robot.home_q, (5, 1))), world, q_current=robot.home_q + 0.1)
    assert [v.time_s for v in _of_kind(report, "step")] == [0.0] * 7


def test_tcp_speed(robot, world):
    q = _home_move(robot, [1.6, 0, 0, 0, 0, 0, 0], duration_s=1.0)  # TCP at 0.4 m radius, peak 3 rad/s
    hits = _of_kind(validate(trajectory(q), world), "tcp_speed")
    assert hits and all(v.value > 1.0 for v in hits) and hits[0].names == ("link_tcp",)


def test_workspace(robot):
    tight = CollisionWorld(
        robot, SafetyConfig(workspace=BoxRegion(min_m=(-0.35, -0.2, -0.005), max_m=(0.95, 0.2, 1.2)))
    )
    report = validate(trajectory(_home_move(robot, [1.0, 0, 0, 0, 0, 0, 0], 3.0)), tight)
    hits = _of_kind(report, "workspace")
    assert any(v.names == ("link_tcp",) for v in hits)
    assert any(v.names[1].startswith("workspace:") for v in hits if len(v.names) == 2)


def test_keep_out(robot):
    target = robot.home_q + np.array([0.8, 0, 0, 0, 0, 0, 0])
    p = robot.tcp_pose(target)[:3, 3]
    box = BoxRegion(name="tray", min_m=tuple(p - 0.05), max_m=tuple(p + 0.05))
    guarded = CollisionWorld(robot, SafetyConfig(keep_out=(box,)))
    hits = _of_kind(validate(trajectory(min_jerk(robot.home_q, target, 3.0)), guarded), "keep_out")
    assert hits and all("keep_out:tray" in v.names for v in hits)
    assert hits[-1].time_s == pytest.approx(3.0)


def test_self_collision(robot, world):
    q1 = robot.home_q.copy()
    q1[1], q1[3] = -1.0, 0.0  # fold the elbow shut
    hits = _of_kind(validate(trajectory(min_jerk(robot.home_q, q1, 4.0)), world), "self_collision")
    assert hits and hits[0].time_s > 0.5  # not at the (free) start
    assert any({n.split("/")[0] for n in v.names} == {"link2", "link5"} for v in hits)


def test_collision_with_box_and_between_samples(robot):
    # a thin wall at y = 0.15 m across the TCP's arc when joint1 turns 0.9 rad from home (TCP radius 0.4 m)
    wall = Primitive("wall", WORLD, "box", (0.2, 0.02, 0.4), pose((0.45, 0.15, 0.25)))
    w = CollisionWorld(robot, obstacles=[wall])
    # two samples only, on either side of the wall: only the sub-sampled motion between them can hit it
    q_far = robot.home_q + np.array([0.9, 0, 0, 0, 0, 0, 0])
    assert not w.in_collision(robot.home_q) and not w.in_collision(q_far)
    coarse = JointTrajectory(tuple(robot.joint_names), 1.0, np.vstack([robot.home_q, q_far]))
    report = validate(coarse, w)
    hits = _of_kind(report, "collision")
    assert hits and all(v.names[1] == "wall" for v in hits)
    assert all(0 < v.time_s < 1.0 for v in hits)
    assert report.configurations_checked == 1 + int(np.ceil(0.9 / w.config.collision_resolution_rad))


def test_gripper_events_change_the_checked_width(robot):
    tcp = robot.tcp_pose(robot.home_q)[:3, 3]
    w = CollisionWorld(robot, obstacles=[Primitive("block", WORLD, "box", (0.06, 0.06, 0.06), pose(tcp))])
    still = np.tile(robot.home_q, (100, 1))
    assert validate(trajectory(still), w).ok  # open gripper around the block
    closing = trajectory(still, events=[GripperEvent(0.2, "close", width_m=0.02)])
    hits = _of_kind(validate(closing, w), "collision")
    assert hits and min(v.time_s for v in hits) == pytest.approx(0.2)
    assert w.gripper_width_m == pytest.approx(robot.spec.gripper.max_width_m)  # restored afterwards


def test_wrong_joint_names_are_refused(robot, world):
    bad = JointTrajectory(tuple(f"j{i}" for i in range(7)), DT, np.tile(robot.home_q, (3, 1)))
    with pytest.raises(TrajectoryError, match="robot joints"):
        validate(bad, world)


def test_subsample_bounds_every_joint_step(robot):
    q = np.vstack([robot.home_q, robot.home_q + np.array([0.05, -0.031, 0, 0.2, 0, 0, 0.009]), robot.home_q])
    configs, times = subsample(q, 0.5, 0.01)
    assert np.max(np.abs(np.diff(configs, axis=0))) <= 0.01 + 1e-12
    assert np.all(np.diff(times) > 0) and times[-1] == pytest.approx(1.0)
    for k, row in enumerate(q):
        assert np.any(np.all(np.isclose(configs, row), axis=1)), k


def test_check_configuration(robot, world):
    assert check_configuration(robot.home_q, world) == []
    q = robot.home_q.copy()
    q[3] = robot.lower[3]
    kinds = {v.kind for v in check_configuration(q, world)}
    assert "joint_limit" in kinds
