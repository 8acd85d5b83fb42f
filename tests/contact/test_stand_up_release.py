"""Standing a small lying can up: the grasp lets go above its goal, so only the poses it takes need to be free.

A can 8 cm long grasped from above and stood up holds the hand sideways at most 6 cm over the table, where the
wrist hangs below the workspace floor. The arm never goes there: it lets go place_lifts_m[0] higher or more, where
the wrist clears the floor. Planning solves the poses the arm takes (each free and in the workspace), so the can is
stood up instead of refused for a pose it never reaches.
"""

from __future__ import annotations

import numpy as np

from motion.cartesian import cartesian_path
from motion.limits import MotionLimits
from motion.manipulation.phases import place_heights
from motion.planner import Planner, PlannerConfig
from motion.segments import scaled_limits
from pipeline.contact.held import held_box
from pipeline.contact.planner import plan_contacts
from pipeline.contact.types import ContactConfig
from runtime.run.contact import lowest_safe_tcp_height
from safety.collision import CollisionWorld
from safety.geometry import transform_points, turn_about

CENTRE_XY = np.array([0.56, -0.12])


def lying_can(
    radius: float, length: float, n: int = 3000, seed: int = 0, centre_xy=CENTRE_XY, yaw: float = 0.0
) -> np.ndarray:
    """The upper half of a can lying on the table at centre_xy, its axis along base x turned yaw about the
    vertical (0: radially away from the robot at CENTRE_XY)."""
    rng = np.random.default_rng(seed)
    along = rng.uniform(-length / 2, length / 2, n)
    angle = rng.uniform(-np.pi / 2, np.pi / 2, n)
    local = np.column_stack([along, radius * np.sin(angle), radius + radius * np.cos(angle)])
    return local @ turn_about(np.zeros(3), np.array([0.0, 0.0, 1.0]), yaw)[:3, :3].T + [*centre_xy, 0.0]


def stand_up(radius: float, length: float, centre_xy=CENTRE_XY, yaw: float = 0.0) -> np.ndarray:
    """x_goal = T x_init: the can turned a quarter turn about the horizontal across its axis through its centre,
    onto its end."""
    centre = np.array([*centre_xy, radius])
    T = turn_about(centre, np.array([-np.sin(yaw), np.cos(yaw), 0.0]), np.pi / 2)
    T[2, 3] += length / 2 - radius  # its end on the table
    return T


def plan(robot, safety, radius: float, length: float, centre_xy=CENTRE_XY, yaw: float = 0.0):
    """Planned as the runtime's contact stage plans (runtime.run.contact): the gate's scene without the table, which
    the contact's own height checks stand for, and with it for the release, the object in the hand."""
    config = ContactConfig(
        min_tcp_height_m=lowest_safe_tcp_height(robot, safety.padding_m),
        collision_padding_m=safety.padding_m,
        place_lifts_m=place_heights(safety.padding_m),
    )
    empty = np.zeros((0, 3))
    world = CollisionWorld(robot, safety, points=empty, table=False)
    points = lying_can(radius, length, centre_xy=centre_xy, yaw=yaw)
    motion = stand_up(radius, length, centre_xy, yaw)
    release_world = CollisionWorld(robot, safety, points=empty)
    return points, plan_contacts(
        points, empty, motion, robot, config=config, collision_world=world, release_world=release_world
    )


def test_a_can_stood_up_by_its_middle_is_let_go_where_the_wrist_clears_the_floor(robot, safety):
    points, result = plan(robot, safety, radius=0.023, length=0.08)
    assert result.ok, result.reason
    for p in result.plans:
        stood = transform_points(p.T_motion, points)
        assert np.ptp(stood[:, 2]) > 0.075  # on its end (8 cm tall), not turned some other way
        release = p.T_place[0]
        assert release[2, 3] >= p.T_goal[2, 3] + place_heights(safety.padding_m)[0] - 1e-9
        assert abs(release[2, 2]) < np.sin(np.radians(ContactConfig().lean_deg)) + 0.01  # sideways (or leaning)
        world = CollisionWorld(robot, safety, points=np.zeros((0, 3)), table=False)
        assert not world.check(p.q_place[0], p.release_width_m)  # the joints it lets go with: free, in the workspace
        np.testing.assert_allclose(robot.tcp_pose(p.q_place[0]), release, atol=2e-3)


def test_a_can_stood_up_far_out_to_the_side_is_let_go_where_the_descent_from_above_reaches(robot, safety):
    # 0.57 m out to the side, the hand sideways just above the stood-up can folds link2 into the base: it is let
    # go higher, the rest a drop, and the joints it is let go with are where the manipulation's straight descent
    # from the pose above arrives (the release's own IK was free while the line's end hit the base, seed 8250)
    radius, length = 0.028, 0.122
    points, result = plan(robot, safety, radius, length, centre_xy=(0.44, -0.36), yaw=np.radians(-56.0))
    assert result.ok, result.reason
    config = ContactConfig()
    lowest = place_heights(safety.padding_m)[0]
    for p in result.plans:
        release = p.T_place[0]
        assert lowest - 1e-9 <= release[2, 3] - p.T_goal[2, 3] <= lowest + config.max_drop_m + 1e-9
        held = held_box(points, p.T_contact, tcp_link=robot.tcp_frame, name="can")
        carrying = CollisionWorld(robot, safety, points=np.zeros((0, 3)), held=held, gripper_width_m=p.width_m)
        limits = scaled_limits(MotionLimits.from_config(safety, robot.spec), 1.0)
        descent = cartesian_path(Planner(carrying, limits, PlannerConfig()), p.q_place[1], release)
        np.testing.assert_allclose(descent[-1], p.q_place[0], atol=1e-3)
