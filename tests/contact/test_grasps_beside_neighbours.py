"""Grasps among neighbours: a grasp from above leaning away from a tall neighbour, the object held as it stands,
and a can nearly as wide as the open gripper.

The knuckles and the hand, 6-18 cm up the fingers, reach wider than the fingertips: a tall object a centimetre
beside a block stops every straight grasp from above (the fingers pass, the hand does not), and a grasp leaning
away from it about its closing axis clears it with the pads on the same faces.
"""

from __future__ import annotations

import numpy as np

from motion.manipulation.phases import place_heights
from pipeline.contact.held import held_box
from pipeline.contact.planner import plan_contacts
from pipeline.contact.sampling import estimate_normals, grasp_candidates
from pipeline.contact.types import ContactConfig
from runtime.run.contact import lowest_safe_tcp_height
from safety.collision import CollisionWorld
from safety.geometry import transform_points

LEAN_DEG = ContactConfig().lean_deg
BLOCK_XY = np.array([0.42, 0.0])
HALF = 0.03  # the block's half size (a 6 cm cube)


def _cube_points(step: float = 0.004) -> np.ndarray:
    """The seen surface of a 6 cm cube on the table at BLOCK_XY: its top and the four sides."""
    g = np.arange(-HALF, HALF + 1e-9, step)
    h = np.arange(0.0, 2 * HALF + 1e-9, step)
    top = np.array([[x, y, 2 * HALF] for x in g for y in g])
    sides = [np.array([[s * HALF, y, z] for y in g for z in h]) for s in (-1, 1)]
    sides += [np.array([[x, s * HALF, z] for x in g for z in h]) for s in (-1, 1)]
    return np.vstack([top, *sides]) + np.array([*BLOCK_XY, 0.0])


def _post(y: float, height: float = 0.15, step: float = 0.005) -> np.ndarray:
    """A tall thin neighbour (a bottle's side) along x beside the block, its face at BLOCK_XY + (0, y)."""
    return np.array(
        [
            [BLOCK_XY[0] + x, BLOCK_XY[1] + y, z]
            for x in np.arange(-0.02, 0.02, step)
            for z in np.arange(0.0, height, step)
        ]
    )


def _plan(robot, safety, scene: np.ndarray):
    config = ContactConfig(
        min_tcp_height_m=lowest_safe_tcp_height(robot, safety.padding_m),
        collision_padding_m=safety.padding_m,
        place_lifts_m=place_heights(safety.padding_m),
    )
    points = _cube_points()
    lift = np.eye(4)
    lift[1, 3] = -0.10  # moved 10 cm away from the neighbour
    world = CollisionWorld(robot, safety, points=scene, table=False)
    release_world = CollisionWorld(robot, safety, points=scene)
    result = plan_contacts(
        points, scene, lift, robot, config=config, collision_world=world, release_world=release_world
    )
    return points, result


def test_a_block_beside_a_tall_neighbour_is_grasped_leaning_away_from_it(robot, safety):
    # the neighbour 1 cm beside the block's +y face, 15 cm tall: the straight grasps' hand (and, closing across y,
    # the finger) meets it
    scene = _post(HALF + 0.01)
    points, result = _plan(robot, safety, scene)
    assert result.ok, result.reason
    for p in result.plans:
        approach = p.T_contact[:3, 2]  # wrist to fingertips
        assert approach[2] < -0.9  # from above
        assert approach[1] > np.sin(np.radians(LEAN_DEG)) - 0.02  # the wrist on the far side from the neighbour
        assert abs(p.T_contact[:3, 1] @ [1.0, 0.0, 0.0]) > 0.99  # closing across the faces beside the neighbour
        # the block is held as it stands: its box in the hand no larger than the block (padded a little)
        held = held_box(points, p.T_contact, tcp_link=robot.tcp_frame, name="block")
        assert max(held.size) < 2 * HALF + 0.01


def test_without_the_neighbour_the_grasp_is_straight_down(robot, safety):
    _, result = _plan(robot, safety, np.zeros((0, 3)))
    assert result.ok, result.reason
    assert result.plans[0].T_contact[2, 2] < -0.999


def test_held_box_of_a_leaning_grasp_is_the_block_upright():
    points = _cube_points()
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])  # from above, closing along base -y
    T[:3, 3] = [*BLOCK_XY, 0.03]
    c, s = np.cos(np.radians(LEAN_DEG)), np.sin(np.radians(LEAN_DEG))
    lean = T.copy()
    lean[:3, :3] = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]) @ T[:3, :3]  # about the closing axis
    for pose in (T, lean):
        box = held_box(points, pose, tcp_link="link_tcp", name="block")
        np.testing.assert_allclose(sorted(box.size), [2 * HALF] * 3, atol=1e-6)
        corners = transform_points(
            pose @ box.T_link_geom,
            np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * np.asarray(box.size) / 2,
        )
        np.testing.assert_allclose(corners.min(axis=0), [*(BLOCK_XY - HALF), 0.0], atol=1e-6)


def test_a_can_nearly_as_wide_as_the_open_gripper_is_grasped(robot):
    # a 76 mm can: the gripper opens 88.9 mm, so 6 mm each side, below the 8 mm clearance kept when there is room
    rng = np.random.default_rng(0)
    radius, height = 0.038, 0.10
    angle, z = rng.uniform(-np.pi, np.pi, 4000), rng.uniform(0.0, height, 4000)
    side = np.column_stack([radius * np.cos(angle), radius * np.sin(angle), z])
    r, a = np.sqrt(rng.uniform(0, 1, 1500)) * radius, rng.uniform(-np.pi, np.pi, 1500)
    top = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(1500, height)])
    points = np.vstack([side, top]) + np.array([0.42, 0.0, 0.0])
    normals = estimate_normals(points, 0.01, np.array([1.0, 0.0, 1.0]))
    config = ContactConfig()
    max_width = robot.spec.gripper.max_width_m
    assert 2 * radius + 2 * config.finger_clearance_m > max_width  # the wide clearance would leave no grasp
    candidates, _ = grasp_candidates(points, normals, config, max_width)
    from_above = [c for c in candidates if c.T_contact[2, 2] < -0.99]
    assert from_above
    assert all(c.object_width_m + 2 * config.min_finger_clearance_m <= max_width for c in from_above)
