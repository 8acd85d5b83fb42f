"""Standing a small lying can up: the grasp lets go above its goal, so only the poses it takes need to be free.

A can 8 cm long grasped from above and stood up holds the hand sideways at most 6 cm over the table, where the
wrist hangs below the workspace floor. The arm never goes there: it lets go place_lifts_m[0] higher or more, where
the wrist clears the floor. Planning solves the poses the arm takes (each free and in the workspace), so the can is
stood up instead of refused for a pose it never reaches.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion.manipulation.phases import place_heights
from pipeline.contact.planner import plan_contacts
from pipeline.contact.types import ContactConfig
from runtime.config import load_profile
from runtime.run.contact import lowest_safe_tcp_height
from safety.collision import CollisionWorld
from safety.geometry import transform_points, turn_about
from safety.robot_model import RobotModel

CONFIG = "configs/sim.yaml"
CENTRE_XY = np.array([0.56, -0.12])


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


@pytest.fixture(scope="module")
def safety():
    return load_profile(CONFIG).safety


def lying_can(radius: float, length: float, n: int = 3000, seed: int = 0) -> np.ndarray:
    """The upper half of a can lying on the table along the base x axis (radially away from the robot)."""
    rng = np.random.default_rng(seed)
    along = rng.uniform(-length / 2, length / 2, n)
    angle = rng.uniform(-np.pi / 2, np.pi / 2, n)
    return np.column_stack(
        [CENTRE_XY[0] + along, CENTRE_XY[1] + radius * np.sin(angle), radius + radius * np.cos(angle)]
    )


def stand_up(radius: float, length: float) -> np.ndarray:
    """x_goal = T x_init: the can turned a quarter turn about the base y axis through its centre, onto its end."""
    centre = np.array([*CENTRE_XY, radius])
    T = turn_about(centre, np.array([0.0, 1.0, 0.0]), np.pi / 2)
    T[2, 3] += length / 2 - radius  # its end on the table
    return T


def plan(robot, safety, radius: float, length: float):
    """Planned as the runtime's contact stage plans (runtime.run.contact): the gate's scene without the table, which
    the contact's own height checks stand for."""
    config = ContactConfig(
        min_tcp_height_m=lowest_safe_tcp_height(robot, safety.padding_m),
        collision_padding_m=safety.padding_m,
        place_lifts_m=place_heights(safety.padding_m),
    )
    empty = np.zeros((0, 3))
    world = CollisionWorld(robot, safety, points=empty, table=False)
    points = lying_can(radius, length)
    return points, plan_contacts(points, empty, stand_up(radius, length), robot, config=config, collision_world=world)


def test_a_can_stood_up_by_its_middle_is_let_go_where_the_wrist_clears_the_floor(robot, safety):
    points, result = plan(robot, safety, radius=0.023, length=0.08)
    assert result.ok, result.reason
    for p in result.plans:
        stood = transform_points(p.T_motion, points)
        assert np.ptp(stood[:, 2]) > 0.075  # on its end (8 cm tall), not turned some other way
        release = p.T_place[0]
        assert release[2, 3] >= p.T_goal[2, 3] + place_heights(safety.padding_m)[0] - 1e-9
        assert abs(release[2, 2]) < 0.3  # the hand sideways, as standing the can up needs
        world = CollisionWorld(robot, safety, points=np.zeros((0, 3)), table=False)
        assert not world.check(p.q_place[0], p.release_width_m)  # the joints it lets go with: free, in the workspace
        np.testing.assert_allclose(robot.tcp_pose(p.q_place[0]), release, atol=2e-3)
