"""The line down to a grasp close to the robot's base (ManipulationChain.descent).

There the elbow folds tight, and the elbow swivel decides whether link4 folds onto link2. Contact planning solves
the pre-contact and contact joints each on its own, so they may lie on two swivels; the seeded IK down the line
keeps the pre-contact's."""

from __future__ import annotations

from itertools import pairwise
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from drivers.config import RobotConfig
from motion.config import MotionConfig
from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.phases import place_heights, plan_manipulation
from pipeline.contact.planner import IK_SETTINGS, plan_contacts
from pipeline.contact.types import ContactConfig
from safety.collision import CollisionWorld

OPEN_M = 0.066  # the approach's finger gap for a 5 cm can


def _top_down(x: float, y: float, z: float, yaw_deg: float) -> np.ndarray:
    """A TCP pose pointing straight down, its closing axis turned yaw_deg about the vertical (base frame)."""
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    T = np.eye(4)
    T[:3, :3] = [[c, s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]]
    T[:3, 3] = (x, y, z)
    return T


def _contact(robot, safety, yaw_deg: float) -> SimpleNamespace:
    """A top-down grasp of a can 0.28 m from the base axis (seed 8258's), its pre-contact 0.1 m above, with the
    joints solved as contact planning solves them: each pose accepted free of collision, the contact seeded by the
    pre-contact."""
    world = CollisionWorld(robot, safety, gripper_width_m=OPEN_M)

    def free(q: np.ndarray) -> bool:
        return not world.in_collision(q, OPEN_M)

    T_contact, T_pre = _top_down(0.25, -0.12, 0.015, yaw_deg), _top_down(0.25, -0.12, 0.115, yaw_deg)
    pre = robot.ik(T_pre, robot.home_q, settings=IK_SETTINGS, accept=free)
    contact = robot.ik(T_contact, pre.q, settings=IK_SETTINGS, accept=free)
    assert pre.success and contact.success
    return SimpleNamespace(T_pre=T_pre, T_contact=T_contact, q_pre=pre.q, q_contact=contact.q)


def _chain(robot, safety, target: np.ndarray) -> ManipulationChain:
    return ManipulationChain(
        robot,
        robot_config=RobotConfig(),
        safety=safety,
        motion=MotionConfig(),
        q_start=robot.home_q,
        scene=np.zeros((0, 3)),
        target=target,
    )


@pytest.fixture
def chain(robot, safety) -> ManipulationChain:
    return _chain(robot, safety, np.zeros((0, 3)))


def _standing_can(x: float, y: float, radius: float = 0.025, height: float = 0.07, n: int = 2500) -> np.ndarray:
    """Points on the side and top of an upright can standing at (x, y) on the table (base frame)."""
    rng = np.random.default_rng(0)
    a, side = rng.uniform(-np.pi, np.pi, n), rng.random(n) < 0.6
    r = np.where(side, radius, radius * np.sqrt(rng.random(n)))
    z = np.where(side, rng.uniform(0.0, height, n), height)
    return np.column_stack([x + r * np.cos(a), y + r * np.sin(a), z])


def test_a_grasp_near_the_base_descends_on_the_contacts_own_swivel(chain, robot, safety):
    c = _contact(robot, safety, yaw_deg=-156.0)
    touching, before = chain.planner(chain.world(OPEN_M)), chain.planner(chain.world(robot.spec.gripper.max_width_m))
    # down from the pre-contact joints, the arm folds link4 onto link2 on the way
    with pytest.raises(ManipulationRefused, match=r"link2/0 / link4/0 \(self_collision\)"):
        chain.line(touching, c.q_pre, c.T_contact, "down")

    path = chain.descent(before, touching, c, "down", "pre-grasp pose")
    np.testing.assert_array_equal(path[-1], c.q_contact)  # ends at the contact's own joints
    assert np.linalg.norm(robot.tcp_pose(path[0])[:3, 3] - c.T_pre[:3, 3]) < 1e-3
    assert before.valid(path[0])  # where the free path ends: valid with the fingers wide open
    assert all(touching.segment_free(a, b) for a, b in pairwise(path))
    s = np.linspace(0.0, 1.0, 11)[:, None]
    dense = np.vstack([a + s * (b - a) for a, b in pairwise(path)])
    off_line = np.linalg.norm(robot.tcp_positions(dense)[:, :2] - c.T_contact[:2, 3], axis=1)
    assert off_line.max() < 0.003  # straight down, not a swing round


def test_a_free_line_down_keeps_the_contacts_pre_contact_joints(chain, robot, safety):
    c = _contact(robot, safety, yaw_deg=30.0)
    touching, before = chain.planner(chain.world(OPEN_M)), chain.planner(chain.world(robot.spec.gripper.max_width_m))
    path = chain.descent(before, touching, c, "down", "pre-grasp pose")
    np.testing.assert_array_equal(path[0], c.q_pre)
    np.testing.assert_array_equal(path, chain.line(touching, c.q_pre, c.T_contact, "down"))


def test_a_can_turned_in_place_close_to_the_base_is_planned_whole(robot, safety):
    # 0.27 m in front of the base: before the descent fell back to the contact's own joints, each of the three
    # best contacts was refused on the way down (link2 / link4), though every one has a free line up
    can = _standing_can(0.27, 0.0)
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler("z", 45.0, degrees=True).as_matrix()
    turn[:3, 3] = [0.27, 0.0, 0.0] - turn[:3, :3] @ [0.27, 0.0, 0.0]  # 45 deg about the can's own axis
    config = ContactConfig(
        place_lifts_m=place_heights(safety.padding_m), collision_padding_m=safety.padding_m, min_tcp_height_m=0.015
    )
    result = plan_contacts(
        can, np.zeros((0, 3)), turn, robot, config=config, collision_world=CollisionWorld(robot, safety, table=False)
    )
    assert result.ok
    chain = _chain(robot, safety, can)
    for contact in result.plans[:3]:
        plan = plan_manipulation(chain, contact)
        assert plan.phase_names == ("approach", "grasp", "carry", "retreat", "home")
        assert all(p.report.ok for p in plan.phases)
