"""Contact in every direction: pushes in eight directions that move an object by what was asked without tipping
it, a grasp let go above a tall container's rim with the fingers clear of its walls, an object stacked on another,
and grasp plans whose set-down poses are free with the object in the hand (what the carry's gate will check)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contact_helpers import clouds, move
from scipy.spatial.transform import Rotation
from test_contact_planner import _box_cloud, _translation

from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.planner import plan_contacts
from pipeline.contact.types import ContactConfig
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

PLACE = ContactConfig(place_lifts_m=(0.025, 0.125), collision_padding_m=0.01, min_tcp_height_m=0.015)


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


def _bowl_cloud(centre, radius, height, n=4000, seed=2):
    """A bowl's wall (inside and out, 8 mm thick) and floor, resting on the table."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi, n)
    r = np.where(rng.random(n) < 0.5, radius, radius - 0.008)
    wall = np.column_stack([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), rng.uniform(0.008, height, n)])
    fa, fr = rng.uniform(0, 2 * np.pi, n // 2), radius * np.sqrt(rng.uniform(0, 1, n // 2))
    floor = np.column_stack([centre[0] + fr * np.cos(fa), centre[1] + fr * np.sin(fa), np.full(n // 2, 0.008)])
    return np.vstack([wall, floor])


def test_a_cube_is_let_go_above_a_tall_bowl_with_the_fingers_clear_of_its_walls(robot):
    cube = _box_cloud((0.40, -0.15), np.array([0.05, 0.05, 0.05]))
    bowl = _bowl_cloud((0.50, 0.12), 0.075, 0.09)
    into = _translation(0.10, 0.27, 0.008 + 0.006)  # resting on the floor, just above it
    world = CollisionWorld(robot, points=bowl, table=False)
    result = plan_contacts(cube, bowl, into, robot, config=PLACE, collision_world=world)
    assert result.ok, result.reason
    boxes = GripperBoxes(robot, 0.01)
    for plan in result.plans:
        release, above = plan.T_place
        drop = release[2, 3] - plan.T_goal[2, 3]
        assert 0.025 < drop <= 0.025 + PLACE.max_drop_m + 1e-9  # let go higher than just above the goal ...
        assert above[2, 3] - release[2, 3] == pytest.approx(0.10)
        assert plan.release_width_m >= plan.open_width_m
        for width in (plan.object_width_m, plan.open_width_m, plan.release_width_m):  # ... the fingers clear the walls
            assert not boxes.hits_points(release, width, bowl)
        carrying = CollisionWorld(robot, points=bowl, held=plan.held)  # the carry's world, the cube in the hand
        for q in plan.q_place:
            assert not carrying.in_collision(q, plan.object_width_m)
    no_drop = plan_contacts(
        cube, bowl, into, robot, config=PLACE.model_copy(update={"max_drop_m": 0.0}), collision_world=world
    )
    assert not no_drop.ok and "at every release height" in no_drop.reason


def test_a_block_is_stacked_on_another(robot):
    top = _box_cloud((0.40, -0.15), np.array([0.05, 0.05, 0.05]))
    below = _box_cloud((0.50, 0.10), np.array([0.06, 0.06, 0.05]), seed=3)
    onto = _translation(0.10, 0.25, 0.05 + 0.006)
    world = CollisionWorld(robot, points=below, table=False)
    result = plan_contacts(top, below, onto, robot, config=PLACE, collision_world=world)
    assert result.ok, result.reason
    for plan in result.plans:
        carrying = CollisionWorld(robot, points=below, held=plan.held)
        assert all(not carrying.in_collision(q, plan.object_width_m) for q in plan.q_place)


@pytest.mark.parametrize("bearing_deg", range(0, 360, 45))
def test_a_push_in_any_of_eight_directions_leads_with_low_fingertips_and_ends_past_the_gap(robot, bearing_deg):
    box = _box_cloud((0.45, 0.0), np.array([0.05, 0.05, 0.08]))
    d = np.array([math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg)), 0.0])
    result = plan_contacts(box, np.zeros((0, 3)), _translation(*(0.08 * d)), robot, mode="push", config=PLACE)
    assert result.ok, result.reason
    plan = result.best
    assert plan.T_contact[:3, 2] @ d > 0.2  # the tips lead, the hand tilted back
    assert plan.T_contact[2, 3] < 0.03  # low: below the tall box's centre of mass (4 cm)
    front = GripperBoxes(robot, 0.0).corners_tcp(robot.spec.gripper.min_width_m, robot.spec.gripper.finger_links)
    reach = float(np.max(front @ plan.T_contact[:3, :3].T @ d))
    back_face = float(np.min(box @ d))
    travelled = float((plan.T_goal[:3, 3] - plan.T_contact[:3, 3]) @ d)
    start_gap = back_face - (plan.T_contact[:3, 3] @ d + reach)
    assert start_gap > 0.005 and travelled == pytest.approx(0.08 + start_gap, abs=0.004)


def _single_scene(tmp_path, objects: str):
    path = tmp_path / "one.yaml"
    path.write_text(f"name: one\nobjects:\n{objects}randomise: {{xy_jitter_m: 0.0, yaw_jitter_deg: 0.0}}\n")
    return str(path)


@pytest.mark.slow
@pytest.mark.parametrize("bearing_deg", range(0, 360, 45))
def test_a_tall_can_pushed_any_way_slides_by_the_shift_without_tipping(robot, sim_profile_with, tmp_path, bearing_deg):
    from drivers.sim import SimArm, SimCamera, SimGripper, SimWorld

    scene = _single_scene(
        tmp_path, "  - {name: can, kind: cylinder, radius_m: 0.025, height_m: 0.11, color: red, xy_m: [0.45, 0.0]}\n"
    )
    profile = sim_profile_with({"sim": {"scene": scene}})
    world = SimWorld(profile.sim, profile.camera)
    camera, arm, gripper = SimCamera(world), SimArm(world), SimGripper(world)
    for device in (camera, arm, gripper):
        device.connect()
    try:
        obj, scene_points, _eye = clouds(world, camera, robot, "can")
        d = np.array([math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg)), 0.0])
        motion = _translation(*(0.08 * d))
        result = plan_contacts(obj, scene_points, motion, robot, mode="push", config=PLACE, q_seed=arm.read_state().q)
        assert result.ok, result.reason
        plan = result.best
        before = world.object_pose("can")
        gripper.command(plan.width_m)
        move(world, arm, plan.q_pre, 2.0)
        move(world, arm, plan.q_contact, 1.5)
        move(world, arm, plan.q_goal, 3.0)  # 8 cm in 3 s: slow, as the push phase is timed
        world.step(0.5)
        after = world.object_pose("can")
        moved = after[:3, 3] - before[:3, 3]
        assert after[2, 2] > math.cos(math.radians(10))  # still upright
        np.testing.assert_allclose(moved[:2], 0.08 * d[:2], atol=0.015)
    finally:
        for device in (camera, arm, gripper):
            device.close()


@pytest.mark.slow
def test_a_push_starts_behind_a_can_and_through_its_axis_on_the_side_the_camera_does_not_see(
    robot, sim_profile_with, tmp_path
):
    """The camera sees a can's near half: the back its rim hides and its middle (half a radius toward the camera
    on the seen points) are where the push must start from, whatever the direction: clear of the can on the way
    down (a finger landing on the rim blocks the arm) and through the axis (off it, a round can slides sideways)."""
    from drivers.sim import SimCamera, SimWorld

    scene = _single_scene(
        tmp_path, "  - {name: can, kind: cylinder, radius_m: 0.035, height_m: 0.112, color: red, xy_m: [0.40, 0.12]}\n"
    )
    profile = sim_profile_with({"sim": {"scene": scene}})
    world = SimWorld(profile.sim, profile.camera)
    camera = SimCamera(world)
    camera.connect()
    try:
        obj, scene_points, _eye = clouds(world, camera, robot, "can")
        axis_xy = world.object_pose("can")[:2, 3]
    finally:
        camera.close()
    front = GripperBoxes(robot, 0.0).corners_tcp(robot.spec.gripper.min_width_m, robot.spec.gripper.finger_links)
    for bearing_deg in range(0, 360, 45):
        d = np.array([math.cos(math.radians(bearing_deg)), math.sin(math.radians(bearing_deg)), 0.0])
        result = plan_contacts(obj, scene_points, _translation(*(0.08 * d)), robot, mode="push", config=PLACE)
        assert result.ok, (bearing_deg, result.reason)
        for plan in result.plans:
            tcp = plan.T_contact[:3, 3]
            off_axis = (tcp[:2] - axis_xy) - ((tcp[:2] - axis_xy) @ d[:2]) * d[:2]
            assert np.linalg.norm(off_axis) < 0.003, (bearing_deg, off_axis)
            reach = float(np.max(front @ plan.T_contact[:3, :3].T @ d))
            gap = (axis_xy @ d[:2] - 0.035) - (tcp @ d + reach)  # fingers' front to the can's true back
            assert gap > 0.008, (bearing_deg, gap)  # most of the 15 mm standoff


def test_both_wrists_are_plans(robot):
    # the parallel gripper is the same turned half a turn about its approach axis, the arm is not: either wrist may
    # be the one whose paths and lines the manipulation finds
    box = _box_cloud((0.45, -0.1), np.array([0.05, 0.05, 0.05]))
    config = PLACE.model_copy(update={"keep": 20})
    result = plan_contacts(box, np.zeros((0, 3)), _translation(0.05, 0.15), robot, config=config)
    assert result.ok, result.reason
    pairs = {}
    for plan in result.plans:
        pairs.setdefault(tuple(np.round(plan.T_contact[:3, 3], 4)), []).append(plan)
    assert any(len(twins) == 2 for twins in pairs.values())
    for twins in pairs.values():
        if len(twins) == 2:
            a, b = twins
            np.testing.assert_allclose(a.T_contact @ np.diag([-1.0, -1.0, 1.0, 1.0]), b.T_contact, atol=1e-9)


def test_a_ball_is_carried_without_the_turn_its_registration_made_up(robot):
    # no turn of a ball shows, so the grounded motion's turn is arbitrary; tilted 60 deg it would put a top grasp
    # on its side at the goal: the plan carries the ball's centre to where the motion puts it, turning nothing
    rng = np.random.default_rng(4)
    d = rng.normal(size=(3000, 3))
    d[:, 2] = np.abs(d[:, 2])  # the upper half the camera sees
    centre = np.array([0.45, -0.1, 0.03])
    ball = centre + 0.03 * d / np.linalg.norm(d, axis=1, keepdims=True)
    motion = np.eye(4)  # turned 60 deg about its centre, then moved 5 cm x 20 cm
    motion[:3, :3] = Rotation.from_euler("x", 60, degrees=True).as_matrix()
    motion[:3, 3] = centre + np.array([0.05, 0.2, 0.0]) - motion[:3, :3] @ centre
    result = plan_contacts(ball, np.zeros((0, 3)), motion, robot, config=PLACE)
    assert result.ok, result.reason
    goal_centre = motion[:3, :3] @ centre + motion[:3, 3]
    for plan in result.plans:
        np.testing.assert_allclose(plan.T_motion[:3, :3], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(plan.T_motion[:3, :3] @ centre + plan.T_motion[:3, 3], goal_centre, atol=1e-3)
