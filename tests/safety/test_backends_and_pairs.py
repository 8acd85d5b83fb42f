"""coal and python-fcl answer the same checks identically; the self-collision pair exclusion is consistent with
the description and its evidence."""

from __future__ import annotations

import numpy as np
import pytest

from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.geometry import WORLD, Primitive, pose, robot_primitives
from safety.self_collision import (
    DISTANCES_FILE,
    candidate_pairs,
    certified_min_distance,
    checked_self_pairs,
    load_certified_distances,
    measure_min_distances,
    padding_reach,
)


def test_coal_and_fcl_agree_on_every_contact(robot):
    rng = np.random.default_rng(7)
    obstacles = [
        Primitive(f"box{i}", WORLD, "box", (0.06, 0.06, 0.06), pose(rng.uniform([0.2, -0.5, 0.03], [0.7, 0.5, 0.4])))
        for i in range(6)
    ]
    obstacles.append(Primitive("ball", WORLD, "sphere", (0.05,), pose((0.4, 0.3, 0.3))))
    obstacles.append(Primitive("can", WORLD, "cylinder", (0.04, 0.2), pose((0.5, -0.3, 0.1))))
    held = Primitive("held:bar", robot.tcp_frame, "box", (0.03, 0.03, 0.12), pose((0.0, 0.0, 0.06)))
    cloud = rng.uniform([0.3, -0.4, 0.0], [0.8, 0.4, 0.15], size=(3000, 3))
    kw = dict(obstacles=obstacles, points=cloud, held=held, gripper_width_m=0.03)
    coal_world, fcl_world = CollisionWorld(robot, **kw), CollisionWorld(robot, **kw, backend="fcl")
    Q = rng.uniform(robot.lower, robot.upper, size=(150, 7))
    fast = [coal_world.in_collision(q) for q in Q]
    assert fast == [fcl_world.in_collision(q) for q in Q]
    assert 0 < sum(fast) < len(Q)
    for q in Q:
        assert coal_world.check(q) == fcl_world.check(q)


def test_unknown_backend_is_refused(robot):
    with pytest.raises(ValueError, match="unknown collision backend"):
        CollisionWorld(robot, backend="bullet")


def test_distance_file_covers_exactly_the_candidate_pairs(robot):
    prims = robot_primitives(robot.spec)
    names = {frozenset((prims[i].name, prims[j].name)) for i, j in candidate_pairs(robot, prims)}
    assert {frozenset(k) for k in load_certified_distances()} == names


def test_neighbours_are_never_candidates(robot):
    prims = robot_primitives(robot.spec)
    pairs = {frozenset((prims[i].link, prims[j].link)) for i, j in candidate_pairs(robot, prims)}
    for a, b in [
        ("link1", "link2"),
        ("link6", "link7"),
        ("link7", "xarm_gripper_base_link"),
        ("left_finger", "right_finger"),
    ]:
        assert frozenset((a, b)) not in pairs
    assert frozenset(("link2", "link5")) in pairs


def test_excluded_pairs_stay_apart_in_fresh_samples(robot):
    """Independent evidence: a new random sample (other seed) finds no excluded pair closer than 2 * padding."""
    pad = SafetyConfig().padding_m
    prims = robot_primitives(robot.spec)
    checked = {frozenset((prims[i].name, prims[j].name)) for i, j in checked_self_pairs(robot, prims, pad)}
    fresh = measure_min_distances(robot, samples=3000, seed=12345)
    excluded = {k: d for k, d in fresh.items() if frozenset(k) not in checked}
    assert excluded, "the certified exclusion should skip some far-apart pairs"
    assert min(excluded.values()) > 2 * pad


def test_padding_reach_is_how_far_a_padded_shape_sticks_out():
    """A box grown by p on each face sticks out sqrt(3) p at its corners, a cylinder sqrt(2) p at its rims."""
    box = Primitive("box", WORLD, "box", (0.2, 0.2, 0.2))
    corner = np.array(box.padded(0.05).size) / 2  # the padded box's corner
    assert np.linalg.norm(corner - np.array(box.size) / 2) == pytest.approx(padding_reach(box, 0.05))
    can = Primitive("can", WORLD, "cylinder", (0.1, 0.3))
    radius, length = can.padded(0.05).size
    rim_out = np.hypot(radius - can.size[0], (length - can.size[1]) / 2)
    assert rim_out == pytest.approx(padding_reach(can, 0.05))
    assert padding_reach(Primitive("cap", WORLD, "capsule", (0.05, 0.2)), 0.05) == pytest.approx(0.05)


def test_certified_bounds_lie_below_every_sampled_distance(robot):
    import yaml

    rows = yaml.safe_load(DISTANCES_FILE.read_text())["pairs"]
    certified = [(a, b, sampled, bound) for a, b, sampled, bound in rows if bound is not None]
    assert len(certified) >= 10 and all(bound <= sampled for _, _, sampled, bound in certified)
    assert all(sampled <= 0.0 for _, _, sampled, bound in rows if bound is None)  # uncertified: they touch


def test_certified_bound_is_recomputed_and_tight(robot):
    """Branch and bound on a two-joint pair (wrist link 6 against a finger): below the true minimum, and close."""
    prims = {p.name: p for p in robot_primitives(robot.spec)}
    a, b = prims["link6/0"], prims["left_finger/knuckle"]
    bound = certified_min_distance(robot, a, b)
    sampled = measure_min_distances(robot, samples=4000, seed=99)[("link6/0", "left_finger/knuckle")]
    assert bound <= sampled < bound + 0.012
    assert bound == pytest.approx(load_certified_distances()[("link6/0", "left_finger/knuckle")], abs=1e-4)


def test_more_padding_checks_more_pairs(robot):
    prims = robot_primitives(robot.spec)
    assert len(checked_self_pairs(robot, prims, 0.0)) <= len(checked_self_pairs(robot, prims, 0.05))
    assert len(checked_self_pairs(robot, prims, 1.0)) == len(candidate_pairs(robot, prims))


def test_cloud_chunks_partition_the_points_and_contacts_are_reported_once(robot):
    from safety.scene import CLOUD_CHUNK_M, split_cloud

    rng = np.random.default_rng(3)
    points = rng.uniform([-0.5, -0.5, 0.0], [0.9, 0.5, 0.6], size=(5000, 3))
    chunks = split_cloud(points, CLOUD_CHUNK_M)
    assert sum(len(c) for c in chunks) == len(points) and len(chunks) > 10
    np.testing.assert_allclose(np.sort(np.vstack(chunks), axis=0), np.sort(points, axis=0))
    for c in chunks:
        assert np.all(np.ptp(np.floor(c / CLOUD_CHUNK_M), axis=0) == 0)  # one grid cell each
    tcp = robot.tcp_pose(robot.home_q)[:3, 3]
    straddling = tcp + np.array([0.0, 0.0, 0.1]) + rng.uniform(-0.15, 0.15, size=(4000, 3))  # over several chunks
    contacts = CollisionWorld(robot, points=straddling).check(robot.home_q)
    cloud_hits = [c.first for c in contacts if c.second == "point_cloud"]
    assert cloud_hits and len(cloud_hits) == len(set(cloud_hits))
