"""Known colliding and free configurations: self, table, workspace, keep-out, boxes, point cloud, held object."""

from __future__ import annotations

import numpy as np
import pytest

from safety.collision import CollisionWorld
from safety.config import BoxRegion, SafetyConfig
from safety.geometry import WORLD, Primitive, pose

FOLDED = np.array([0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0])  # elbow closed: forearm lies along the upper arm


@pytest.fixture(scope="module")
def world(robot) -> CollisionWorld:
    return CollisionWorld(robot)


def _tcp(robot, q) -> np.ndarray:
    return robot.tcp_pose(q)[:3, 3]


def _lowered(robot, dz: float) -> np.ndarray:
    """Home posture moved straight down by dz (IK), gripper still pointing down."""
    T = robot.tcp_pose(robot.home_q)
    T[2, 3] -= dz
    res = robot.ik(T, q_seed=robot.home_q)
    assert res.success, res.reason
    return res.q


def _kinds(contacts) -> set[str]:
    return {c.kind for c in contacts}


def test_home_is_free(world, robot):
    assert not world.in_collision(robot.home_q)
    assert world.check(robot.home_q) == []


def test_folded_elbow_self_collides(world):
    contacts = world.check(FOLDED)
    assert world.in_collision(FOLDED)
    assert _kinds(contacts) == {"self_collision"}
    assert any({c.first.split("/")[0], c.second.split("/")[0]} == {"link2", "link5"} for c in contacts)


def test_fingertips_into_the_table_collide(world, robot):
    # home TCP is 0.228 m above the table; the fingertips reach ~3 cm below the TCP... lower by 0.22 m
    q = _lowered(robot, 0.22)
    contacts = world.check(q)
    assert any(c.second == "table" and "finger" in c.first for c in contacts)
    assert not world.in_collision(_lowered(robot, 0.1))


def test_padding_is_applied(robot):
    # TCP 6 mm above the table: the finger pads end ~2 mm above the TCP...; padding decides
    q = _lowered(robot, 0.228 - 0.05)
    tight = CollisionWorld(robot, SafetyConfig(padding_m=0.0))
    loose = CollisionWorld(robot, SafetyConfig(padding_m=0.06))
    assert not tight.in_collision(q)
    assert loose.in_collision(q)


def test_box_obstacle_at_the_gripper(robot):
    # the TCP sits between the open fingers (gap 8.9 cm, 6.9 cm once padded): a 6 cm box fits, a 10 cm one hits
    tcp = _tcp(robot, robot.home_q)
    w = CollisionWorld(robot, obstacles=[Primitive("crate", WORLD, "box", (0.06, 0.06, 0.06), pose(tcp))])
    assert not w.in_collision(robot.home_q)
    w.set_obstacles([Primitive("crate", WORLD, "box", (0.1, 0.1, 0.06), pose(tcp))])
    assert w.in_collision(robot.home_q)
    assert any(c.second == "crate" and c.kind == "collision" and "finger" in c.first for c in w.check(robot.home_q))
    w.set_obstacles([Primitive("crate", WORLD, "box", (0.1, 0.1, 0.06), pose(tcp + np.array([0, 0.4, 0])))])
    assert not w.in_collision(robot.home_q)
    w.set_obstacles([Primitive("crate", WORLD, "box", (0.06, 0.06, 0.06), pose(tcp))])
    assert w.in_collision(robot.home_q, gripper_width_m=0.02)  # closing the gripper on it: the pads touch


@pytest.mark.parametrize("kind,size", [("sphere", (0.04,)), ("cylinder", (0.03, 0.1))])
def test_sphere_and_cylinder_obstacles(robot, kind, size):
    at = _tcp(robot, robot.home_q) + np.array([0.0, 0.0, 0.1])  # around the gripper body
    w = CollisionWorld(robot, obstacles=[Primitive("thing", WORLD, kind, size, pose(at))])
    assert w.in_collision(robot.home_q)
    w.set_obstacles([Primitive("thing", WORLD, kind, size, pose(at + np.array([0.0, 0.5, 0.0])))])
    assert not w.in_collision(robot.home_q)


def test_point_cloud_obstacle(robot):
    rng = np.random.default_rng(0)
    blob = (
        _tcp(robot, robot.home_q) + np.array([0.0, 0.0, 0.1]) + rng.uniform(-0.02, 0.02, size=(500, 3))
    )  # gripper body
    w = CollisionWorld(robot, points=blob)
    assert w.in_collision(robot.home_q)
    assert any(c.second == "point_cloud" for c in w.check(robot.home_q))
    w.set_points(blob + np.array([0.0, 0.5, 0.0]))
    assert not w.in_collision(robot.home_q)
    w.set_points(None)
    assert not w.in_collision(robot.home_q)


def test_held_object_moves_with_the_tcp(robot):
    # a 12 cm long box held 6 cm below the TCP: free at home, into the table when lowered by 0.15 m while the
    # fingers themselves stay above the table
    held = Primitive("held:bar", robot.tcp_frame, "box", (0.03, 0.03, 0.12), pose((0.0, 0.0, 0.06)))
    w = CollisionWorld(robot, held=held, gripper_width_m=0.03)
    plain = CollisionWorld(robot, gripper_width_m=0.03)
    assert not w.in_collision(robot.home_q)
    q = _lowered(robot, 0.15)
    assert not plain.in_collision(q)
    contacts = w.check(q)
    assert any(c.first == "held:bar" and c.second == "table" for c in contacts)
    w.set_held_object(None)
    assert not w.in_collision(q)


def test_a_held_tool_may_be_checked_with_its_own_smaller_margin(robot):
    # a tool whose underside hangs 5 mm above the table: inside the robot's 10 mm padding, outside a 2 mm margin;
    # the robot's own shapes keep the full padding, and a margin above the padding is refused
    T = robot.tcp_pose(robot.home_q)
    res = robot.ik(pose((T[0, 3], T[1, 3], 0.06)) @ np.diag([1.0, -1.0, -1.0, 1.0]), q_seed=robot.home_q)
    assert res.success, res.reason
    held = Primitive("held:brush", robot.tcp_frame, "box", (0.05, 0.12, 0.03), pose((0.0, 0.0, 0.06 - 0.005 - 0.015)))
    padded = CollisionWorld(robot, held=held, gripper_width_m=0.02)
    own = CollisionWorld(robot, held=held, gripper_width_m=0.02, held_padding_m=0.002)
    assert any(c.first == "held:brush" and c.second == "table" for c in padded.check(res.q))
    assert not own.in_collision(res.q) and own.copy().check(res.q) == []
    with pytest.raises(ValueError, match="held_padding_m"):
        CollisionWorld(robot, held=held, held_padding_m=0.05)


def test_workspace_and_keep_out(robot):
    tcp = _tcp(robot, robot.home_q)
    narrow = SafetyConfig(workspace=BoxRegion(min_m=(-0.35, -0.7, -0.005), max_m=(0.3, 0.7, 1.2)))
    assert "workspace" in _kinds(CollisionWorld(robot, narrow).check(robot.home_q))
    guarded = SafetyConfig(keep_out=(BoxRegion(name="operator", min_m=tuple(tcp - 0.05), max_m=tuple(tcp + 0.05)),))
    contacts = CollisionWorld(robot, guarded).check(robot.home_q)
    assert any(c.kind == "keep_out" and c.second == "keep_out:operator" for c in contacts)


def test_fast_path_agrees_with_detailed_check(robot):
    rng = np.random.default_rng(1)
    obstacles = [
        Primitive(f"b{i}", WORLD, "box", (0.1, 0.1, 0.1), pose(rng.uniform([0.2, -0.5, 0], [0.7, 0.5, 0.4])))
        for i in range(5)
    ]
    w = CollisionWorld(
        robot, obstacles=obstacles, points=rng.uniform([0.3, -0.3, 0.0], [0.6, 0.3, 0.2], size=(2000, 3))
    )
    Q = rng.uniform(robot.lower, robot.upper, size=(300, 7))
    hits = [w.in_collision(q) for q in Q]
    assert hits == [bool(w.check(q)) for q in Q]
    assert 0 < sum(hits) < len(Q)


def test_per_call_gripper_width_does_not_stick(robot):
    tcp = _tcp(robot, robot.home_q)
    w = CollisionWorld(robot, obstacles=[Primitive("block", WORLD, "box", (0.06, 0.06, 0.06), pose(tcp))])
    assert w.in_collision(robot.home_q, gripper_width_m=0.02)
    assert not w.in_collision(robot.home_q)  # back to the world's own (open) width
    w.set_gripper_width(0.02)
    assert w.in_collision(robot.home_q) and w.gripper_width_m == pytest.approx(0.02)
