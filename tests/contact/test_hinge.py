"""Hinge push: the hinge line recovered from a part's motion, and the arc of TCP poses that turns the part."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.hinge import END_GAP_MIN_M, HingeError, arc_candidates, hinge_from_motion
from pipeline.contact.planner import plan_contacts
from pipeline.contact.types import ContactConfig
from safety.geometry import transform_points
from safety.robot_model import RobotModel

HINGE_POINT = np.array([0.44, 0.0, 0.07])  # the back top edge of a box, the edge nearer the robot
LID_M = 0.12  # from the hinge to the free edge
THICKNESS_M = 0.008


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


@pytest.fixture(scope="module")
def fingers(robot):
    g = robot.spec.gripper
    return GripperBoxes(robot, 0.0).corners_tcp(g.min_width_m, g.finger_links)


def turn_about(axis, point, angle_deg) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(math.radians(angle_deg) * np.asarray(axis) / np.linalg.norm(axis)).as_matrix()
    T[:3, 3] = point - T[:3, :3] @ point
    return T


def open_lid(open_deg: float, n: int = 2000, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The points a camera beyond the box sees of a lid opened open_deg (its inner face), and the closing motion.

    The lid is a plate hinged along base y; closed it lies over the box (+x of the hinge), its inner face down.
    """
    rng = np.random.default_rng(seed)
    closed = np.column_stack([rng.uniform(0, LID_M, n), rng.uniform(-0.08, 0.08, n), np.zeros(n)]) + HINGE_POINT
    opening = turn_about([0.0, -1.0, 0.0], HINGE_POINT, open_deg)  # opens upward, toward the robot
    return transform_points(opening, closed), np.linalg.inv(opening)


def test_a_turn_about_a_line_gives_that_line_and_angle():
    axis = np.array([0.3, -0.9, 0.2]) / np.linalg.norm([0.3, -0.9, 0.2])
    point = np.array([0.5, 0.1, 0.2])
    hinge = hinge_from_motion(turn_about(axis, point, 100.0), 0.005, 5.0)
    assert math.degrees(hinge.angle_rad) == pytest.approx(100.0)
    np.testing.assert_allclose(hinge.axis, axis, atol=1e-9)
    off_line = (hinge.point - point) - ((hinge.point - point) @ axis) * axis
    assert np.linalg.norm(off_line) < 1e-9
    np.testing.assert_allclose(hinge.turn(hinge.angle_rad), turn_about(axis, point, 100.0), atol=1e-9)


def test_a_turn_the_other_way_flips_the_axis_not_the_angle():
    hinge = hinge_from_motion(turn_about([0, 1, 0], HINGE_POINT, -40.0), 0.005, 5.0)
    assert math.degrees(hinge.angle_rad) == pytest.approx(40.0)
    np.testing.assert_allclose(hinge.axis, [0, -1, 0], atol=1e-9)


@pytest.mark.parametrize(
    ("slide", "angle_deg", "reason"),
    [
        ([0.0, 0.02, 0.0], 90.0, "slides 20 mm along its rotation axis"),
        ([0.1, 0.0, 0.0], 2.0, "turns 2.0 deg, below the 5 deg"),
        ([0.1, 0.0, 0.0], 0.0, "turns 0.0 deg"),
    ],
)
def test_a_motion_no_hinge_makes_is_refused_with_the_reason(slide, angle_deg, reason):
    T = turn_about([0, 1, 0], HINGE_POINT, angle_deg)
    T[:3, 3] += slide
    with pytest.raises(HingeError, match=reason):
        hinge_from_motion(T, 0.005, 5.0)


def test_arc_poses_follow_the_lid_from_open_to_just_above_closed(fingers):
    cfg = ContactConfig()
    points, closing = open_lid(100.0)
    hinge = hinge_from_motion(closing, cfg.hinge_max_slide_m, cfg.hinge_min_turn_deg)
    candidates, rejected = arc_candidates(points, hinge, cfg, fingers)
    assert len(candidates) == 3 and not rejected
    outward_open = np.linalg.inv(closing)[:3, :3] @ np.array([0.0, 0.0, 1.0])  # pushed face (up when closed), open
    for c in candidates:
        poses = [c.T_contact, *c.via, c.T_goal]
        assert len(poses) == 11  # 100 deg in steps of 10
        for k, T in enumerate(poses[:-1]):  # pose k keeps the fingers off the lid turned 10k deg toward closed
            np.testing.assert_allclose(T[:3, :3], c.T_contact[:3, :3], atol=1e-12)  # orientation fixed
            outward = hinge.turn(math.radians(10.0 * k))[:3, :3] @ outward_open
            gap = (transform_points(T, fingers) - HINGE_POINT) @ outward
            assert gap.min() == pytest.approx(cfg.push_standoff_m, abs=1e-6)  # nearest finger corner off the face
        radial = np.linalg.norm(np.cross(c.T_contact[:3, 3] - hinge.point, hinge.axis))
        assert 0.75 * LID_M < radial < LID_M  # near the free edge
        assert c.T_contact[2, 2] < -0.95  # fingers along the lid (10 deg past vertical), pointing to the hinge
        assert c.T_contact[0, 0] > 0.9  # TCP x away from the base, as at home: no half turn of the wrist
        lowest = transform_points(c.T_goal, fingers)[:, 2].min()  # nothing under the lid: a lid's thickness above
        assert lowest == pytest.approx(HINGE_POINT[2] + END_GAP_MIN_M, abs=1e-6)
    lateral = sorted(c.T_contact[1, 3] for c in candidates)
    assert lateral[0] < -0.015 and abs(lateral[1]) < 0.005 and lateral[2] > 0.015


def test_the_arc_ends_as_near_the_shut_lid_as_the_gate_passes_over_the_rim_it_closes_on(robot):
    """A stiff hinge holds a lid where the fingers leave it: the push ends at the least gap the gate passes over the
    box's rim, which it sees as octree cells (the raw points with the padding alone put the fingers in a cell)."""
    from safety.collision import CollisionWorld
    from safety.config import SafetyConfig

    safety = SafetyConfig()
    rng = np.random.default_rng(1)
    x, y = rng.uniform(0, LID_M, 4000), rng.uniform(-0.08, 0.08, 4000)
    edge = rng.integers(0, 4, 4000)  # the four walls' top edges, under the shut lid's rim
    x = np.where(edge == 0, 0.004, np.where(edge == 1, LID_M - 0.004, x))
    y = np.where(edge == 2, -0.076, np.where(edge == 3, 0.076, y))
    # the rim's top 0.2 mm above a cell's boundary (z = 7 cm): the cell it is in reaches a centimetre higher
    rim = np.column_stack([x, y, rng.uniform(-0.01, 0.0002, 4000)]) + HINGE_POINT
    rim = rim[np.isin(edge, (0, 1)) | (np.abs(rim[:, 1]) > 0.07)]
    points, closing = open_lid(100.0)
    world = CollisionWorld(robot, safety, points=rim, table=False)
    cfg = ContactConfig(collision_padding_m=safety.padding_m)
    result = plan_contacts(
        points, rim, closing, robot, mode="hinge", config=cfg, collision_world=world, viewpoint=np.array([1.1, 0, 0.8])
    )
    assert result.ok, result.reason
    g = robot.spec.gripper
    fingers = GripperBoxes(robot, 0.0).corners_tcp(g.min_width_m, g.finger_links)
    for plan in result.plans:
        assert not world.in_collision(plan.q_goal, g.min_width_m)  # the gate passes the end
        gap = transform_points(plan.T_goal, fingers)[:, 2].min() - HINGE_POINT[2]
        # nearer than the standoff and lift it ended at before (a lid of 12 cm left 12 deg open), off the rim
        assert safety.padding_m < gap < cfg.push_standoff_m + 0.01 - 0.003


def test_planner_returns_reachable_arc_plans_and_refuses_a_slide(robot):
    points, closing = open_lid(100.0)
    result = plan_contacts(points, np.zeros((0, 3)), closing, robot, mode="hinge", viewpoint=np.array([1.1, 0, 0.8]))
    assert result.ok, result.reason
    for plan in result.plans:
        assert plan.mode == "hinge" and plan.width_m == pytest.approx(robot.spec.gripper.min_width_m)
        assert len(plan.via) == len(plan.q_via) == 9
        outward = np.linalg.inv(closing)[:3, :3] @ np.array([0.0, 0.0, 1.0])  # the open lid's outer face
        back = (plan.T_pre[:3, 3] - plan.T_contact[:3, 3]) / ContactConfig().pre_distance_m
        slant = math.degrees(math.asin(back @ outward))  # the fingers come in slanted in front of the face
        assert slant == pytest.approx(ContactConfig().hinge_approach_deg)
        assert back @ -plan.T_contact[:3, 2] == pytest.approx(math.cos(math.radians(slant)))  # from beyond the edge
        for T, q in zip((*plan.via, plan.T_goal), (*plan.q_via, plan.q_goal), strict=True):
            np.testing.assert_allclose(robot.tcp_pose(q), T, atol=1e-4)
    sliding = closing.copy()
    sliding[1, 3] += 0.03
    refused = plan_contacts(points, np.zeros((0, 3)), sliding, robot, mode="hinge")
    assert not refused.ok and "slides 30 mm along its rotation axis" in refused.reason
