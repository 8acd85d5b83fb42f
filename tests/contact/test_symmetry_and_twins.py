"""Freedoms the contact planner uses when a candidate as sampled cannot be reached: the gripper's half turn about
its approach axis (the same grasp, the other wrist), a body of revolution's turn about its own axis (the same goal
to the eye), and the heights the object is set down from (checked as part of the goal)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from test_contact_planner import _box_cloud, _translation

from pipeline.contact.planner import plan_contacts
from pipeline.contact.symmetry import revolution_axis, turn_deg
from pipeline.contact.types import ContactConfig
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

RADIUS, LENGTH = 0.03, 0.18


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


@pytest.fixture(scope="module")
def arm_only(robot):
    """Self-collision, workspace and keep-out only, as the runtime's contact stage passes (plus its scene)."""
    return CollisionWorld(robot, table=False)


def _lying_cylinder(
    x: float, y: float, n: int = 2500, seed: int = 0, arc: tuple[float, float] = (0.1 * np.pi, 0.9 * np.pi)
) -> np.ndarray:
    """The surface a camera sees of a cylinder lying along base y on the table: the arc of angles about its axis
    (from base +x towards up), by default its upper surface (a camera above)."""
    rng = np.random.default_rng(seed)
    along = rng.uniform(-LENGTH / 2, LENGTH / 2, n)
    a = rng.uniform(*arc, n)
    return np.column_stack([x + RADIUS * np.cos(a), y + along, RADIUS + RADIUS * np.sin(a)])


def _stand_up(x: float, y: float, yaw_deg: float) -> np.ndarray:
    """x_goal = T x: the lying cylinder stood on its -y end, then turned yaw_deg about its now vertical axis."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xz", [90.0, yaw_deg], degrees=True).as_matrix()
    T[:3, 3] = np.array([x, y, LENGTH / 2]) - T[:3, :3] @ np.array([x, y, RADIUS])
    return T


def test_the_axis_of_a_lying_cylinder_is_found_from_its_seen_half_and_a_box_has_none():
    axis = revolution_axis(_lying_cylinder(0.45, 0.05))
    assert axis is not None
    assert abs(axis.direction[1]) > 0.999
    np.testing.assert_allclose(axis.point[[0, 2]], [0.45, RADIUS], atol=0.002)
    assert axis.radius_m == pytest.approx(RADIUS, abs=0.002)
    assert revolution_axis(_box_cloud((0.45, 0.0), np.array([0.05, 0.05, 0.05]))) is None
    turn = axis.turn(np.radians(70.0))
    on_axis = axis.point + 0.05 * axis.direction
    np.testing.assert_allclose(turn[:3, :3] @ on_axis + turn[:3, 3], on_axis, atol=1e-12)


def test_the_axis_of_a_short_lying_can_whose_end_is_seen_too_lies_level_on_the_table():
    # the principal direction of a short, wide can's seen half and end leans 5 deg out of the table's plane: turned
    # about it, the goal's turns stood the can up leaning and put the hand where the arm could not (seed 9030)
    rng = np.random.default_rng(0)
    radius, length = 0.027, 0.1
    along, a = rng.uniform(-length / 2, length / 2, 1500), rng.uniform(0.1 * np.pi, 0.9 * np.pi, 1500)
    side = np.column_stack([radius * np.cos(a), along, radius + radius * np.sin(a)])
    r, t = radius * np.sqrt(rng.uniform(0, 1, 300)), rng.uniform(0, 2 * np.pi, 300)
    end = np.column_stack([r * np.cos(t), np.full(300, length / 2), radius + r * np.sin(t)])
    end = end[(np.cos(t) > -0.3) & (end[:, 2] > 0.005)]  # the end's part the camera sees above the table
    axis = revolution_axis(np.vstack([side, end]) + np.array([0.6, 0.03, 0.0]))
    assert axis is not None
    assert abs(axis.direction[2]) < np.sin(np.radians(1.0))
    np.testing.assert_allclose(axis.point[[0, 2]], [0.6, radius], atol=0.002)
    assert axis.radius_m == pytest.approx(radius, abs=0.002)


def test_a_stand_up_ending_with_the_wrist_behind_the_bottle_is_turned_about_the_bottle_axis(robot, arm_only):
    # turned 90 deg after standing up, every top grasp would end with the gripper pointing back at the robot
    cylinder, motion = _lying_cylinder(0.45, 0.0), _stand_up(0.45, 0.0, 90.0)
    config = ContactConfig(place_lifts_m=(0.025, 0.125), collision_padding_m=0.01, min_tcp_height_m=0.015)
    result = plan_contacts(cylinder, np.zeros((0, 3)), motion, robot, config=config, collision_world=arm_only)
    assert result.ok, result.reason
    axis = revolution_axis(cylinder)
    ends = np.array([axis.point + s * axis.direction for s in (-0.08, 0.08)])
    for plan in result.plans:
        realised = plan.T_motion
        assert not np.allclose(realised[:3, :3], motion[:3, :3], atol=1e-3)  # not the grounded turn ...
        moved = lambda T: ends @ T[:3, :3].T + T[:3, 3]  # noqa: E731
        np.testing.assert_allclose(moved(realised), moved(motion), atol=1e-9)  # ... but the same axis: same goal
        np.testing.assert_allclose(plan.T_goal, realised @ plan.T_contact, atol=1e-12)
        np.testing.assert_allclose(robot.tcp_pose(plan.q_goal), plan.T_goal, atol=1e-4)
        assert not arm_only.in_collision(plan.q_goal)


def test_a_wrist_that_folds_onto_itself_is_planned_half_turned(robot, arm_only):
    # closing along base x at this spot, the sampled wrist folds link5 onto link7 (link7 is off its axis); the
    # same grasp half turned about the approach axis is free
    box = _box_cloud((0.462, -0.12), np.array([0.05, 0.05, 0.05]))
    config = ContactConfig(yaw_step_deg=90.0)  # samples closing axes +x and +y only
    result = plan_contacts(
        box, np.zeros((0, 3)), _translation(0.0, 0.1), robot, config=config, collision_world=arm_only
    )
    assert result.ok, result.reason
    closing = [np.round(p.T_contact[:3, 1], 3) for p in result.plans]
    assert any(np.allclose(y, [-1.0, 0.0, 0.0], atol=0.01) for y in closing), closing  # the half turn of +x
    for plan in result.plans:
        for q in (plan.q_pre, plan.q_contact, plan.q_goal):
            assert not arm_only.in_collision(q)


def test_the_heights_the_object_is_set_down_from_must_be_reachable_too(robot):
    box = _box_cloud((0.45, 0.0), np.array([0.05, 0.05, 0.05]))
    far = _translation(0.2, 0.0)  # set down 0.65 m out: reachable at the table, not a metre above it (from above
    # or, the hand turned sideways, from the side)
    assert plan_contacts(box, np.zeros((0, 3)), far, robot).ok
    lifted = plan_contacts(box, np.zeros((0, 3)), far, robot, config=ContactConfig(place_lifts_m=(1.0,)))
    assert not lifted.ok
    assert "pose to let go from out of reach" in lifted.reason


def test_plans_realising_the_grounded_motion_rank_before_turned_ones_and_those_by_their_grasp(robot, arm_only):
    # here one grasp reaches its goal as grounded and another only turned about the axis; the verification's
    # registration may see part of such a turn, so the plans that need none come first; the turned ones then by
    # how good a grasp they are, the least turn only breaking ties (which turn a contact gets is the first its
    # wrist reaches: ranked by it, a slanted grasp that turned a stood-up bottle in the fingers came first)
    cylinder, motion = _lying_cylinder(0.45, 0.05), _stand_up(0.45, 0.05, 0.0)
    config = ContactConfig(place_lifts_m=(0.025, 0.125), collision_padding_m=0.01, min_tcp_height_m=0.015)
    result = plan_contacts(cylinder, np.zeros((0, 3)), motion, robot, config=config, collision_world=arm_only)
    turns = [round(turn_deg(p.T_motion, motion)) for p in result.plans]
    assert turns[0] == 0 and max(turns) > 0
    grounded = turns.count(0)
    assert turns[:grounded] == [0] * grounded
    turned = [(-round(p.score, 3), t) for p, t in zip(result.plans[grounded:], turns[grounded:], strict=True)]
    assert turned == sorted(turned)


def test_a_stood_up_bottle_is_let_go_with_the_fingers_wide_open_where_nothing_is_near(robot, arm_only):
    # the cloud's width across the fingers is below the bottle's (one camera sees only part of it): opened only to
    # the approach's gap the fingers stayed on the stood-up bottle, and backing off dragged it over (seed 106)
    cylinder, motion = _lying_cylinder(0.45, 0.0), _stand_up(0.45, 0.0, 90.0)
    config = ContactConfig(place_lifts_m=(0.025, 0.125), collision_padding_m=0.01, min_tcp_height_m=0.015)
    result = plan_contacts(cylinder, np.zeros((0, 3)), motion, robot, config=config, collision_world=arm_only)
    assert result.ok, result.reason
    widest = robot.spec.gripper.max_width_m
    for plan in result.plans:
        assert plan.release_width_m == pytest.approx(widest) and plan.release_width_m > plan.open_width_m
        assert not arm_only.in_collision(plan.q_place[0], plan.release_width_m)


def test_a_lying_cylinder_seen_from_one_side_is_pinched_about_its_axis_with_the_fingers_open_wider_than_it(
    robot, arm_only
):
    # a camera in front of the robot sees a lying bottle's top and its side away from the robot: pinched between
    # the seen points, the fingers were centred 1.5 cm off the axis towards the camera and opened narrower than the
    # bottle, a finger came down on it and rolled it in the hand, and it was stood up 3 cm off its goal (seed 8238)
    centre = np.array([0.45, 0.05, RADIUS])
    seen = _lying_cylinder(*centre[:2], arc=(-0.3 * np.pi, 0.6 * np.pi))
    config = ContactConfig(place_lifts_m=(0.025, 0.125), collision_padding_m=0.01, min_tcp_height_m=0.015)
    result = plan_contacts(
        seen, np.zeros((0, 3)), _stand_up(*centre[:2], 0.0), robot, config=config, collision_world=arm_only
    )
    assert result.ok, result.reason
    for plan in result.plans:
        closing = plan.T_contact[:3, 1]
        assert abs(closing[2]) < 0.1  # across the lying cylinder, from above or the side
        assert abs((plan.T_contact[:3, 3] - centre) @ closing) < 0.003  # the fingers either side of its axis
        assert plan.object_width_m >= 2 * RADIUS - 0.002
        assert plan.open_width_m > 2 * RADIUS + 0.01
        # ... and close below what the seen points show between them, not below the completed width: an axis a few
        # millimetres off widens that, and the fingers closed too lightly on an upright bottle to hold it (seed 9115)
        assert plan.width_m < plan.object_width_m - config.squeeze_m - 0.01


def test_a_box_whose_turns_no_image_shows_is_carried_by_the_goals_least_turning_twin(robot):
    """A uniform cube the goal turns a quarter about the vertical and moves 12 cm: that turn is one grounding
    reports the images cannot show, so the plans carry the cube there unturned; unreported, the turn is made."""
    from pipeline.grounding.types import SeenSymmetry

    centre, goal = np.array([0.45, -0.05, 0.025]), np.array([0.45, 0.07, 0.025])
    cube = _box_cloud(centre[:2], np.array([0.05, 0.05, 0.05]))
    quarter = Rotation.from_euler("z", 90.0, degrees=True).as_matrix()
    motion = _translation(0.0, 0.12)
    motion[:3, :3], motion[:3, 3] = quarter, goal - quarter @ centre
    turns = Rotation.from_euler("z", [[0.0], [90.0], [180.0], [270.0]], degrees=True).as_matrix()
    hidden = SeenSymmetry("box", centre, rotations=turns, shape_kind="box").box_turns_in(np.eye(4))
    for reported, turned_deg in ((hidden, 0.0), (None, 90.0)):
        result = plan_contacts(cube, np.zeros((0, 3)), motion, robot, hidden_turns=reported)
        assert result.ok, result.reason
        for plan in result.plans:
            assert turn_deg(plan.T_motion, np.eye(4)) == pytest.approx(turned_deg, abs=1e-6)
            np.testing.assert_allclose(plan.T_motion[:3, :3] @ centre + plan.T_motion[:3, 3], goal, atol=1e-9)
