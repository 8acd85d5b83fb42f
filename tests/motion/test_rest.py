"""Where a manipulation ends: home, or above it where what the plan put down stands in the home gripper's way."""

from __future__ import annotations

import numpy as np

from motion.manipulation.chain import REST_RAISE_MAX_M, ManipulationChain
from runtime.config import load_profile

CONFIG = "configs/sim.yaml"


def _chain(robot, scene: np.ndarray) -> ManipulationChain:
    profile = load_profile(CONFIG)
    return ManipulationChain(
        robot,
        robot_config=profile.robot,
        safety=profile.safety,
        motion=profile.motion,
        q_start=robot.home_q,
        scene=scene,
        target=np.zeros((0, 3)),
    )


def _column(x: float, y: float, radius: float, height: float) -> np.ndarray:
    """The surface of an upright cylinder (a stood-up bottle) as points, base frame."""
    a, z = np.meshgrid(np.linspace(0.0, 2 * np.pi, 40, endpoint=False), np.linspace(0.0, height, 40))
    return np.column_stack([x + radius * np.cos(a).ravel(), y + radius * np.sin(a).ravel(), z.ravel()])


def test_a_plan_ends_at_home_raised_clear_of_a_bottle_stood_up_under_the_home_gripper(robot):
    # seed 8226: a 21 cm bottle stood up where it lay, under the home gripper; every plan was refused on its way
    # home, home itself in the bottle
    chain = _chain(robot, np.zeros((0, 3)))
    T_home = robot.tcp_pose(chain.home)
    bottle = _column(*(T_home[:2, 3] + [0.02, 0.035]), 0.029, 0.214)  # under a finger, not between the two
    world = chain.world(robot.spec.gripper.max_width_m, obstacle=bottle)
    planner = chain.planner(world)
    assert not planner.valid(chain.home)
    q = chain.rest(world)
    assert planner.valid(q)
    T = robot.tcp_pose(q)
    np.testing.assert_allclose(T[:2, 3], T_home[:2, 3], atol=1e-3)  # straight above home, as turned
    np.testing.assert_allclose(T[:3, :3], T_home[:3, :3], atol=1e-3)
    assert T_home[2, 3] < T[2, 3] <= T_home[2, 3] + REST_RAISE_MAX_M + 1e-9


def test_a_plan_ends_at_home_itself_where_nothing_is_in_its_way(robot):
    chain = _chain(robot, _column(0.6, -0.3, 0.03, 0.2))
    world = chain.world(robot.spec.gripper.max_width_m)
    np.testing.assert_array_equal(chain.rest(world), chain.home)
