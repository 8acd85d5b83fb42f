"""OMPL planning in the safety collision world: direct moves, detours around obstacles, gate re-check."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from conftest import wall_between

from motion.approval import approve, gate_check
from motion.planner import Planner, PlannerConfig, PlanningError
from safety.collision import CollisionWorld
from safety.geometry import Primitive, pose

Q_LEFT = np.array([0.7, 0.2, 0.0, 0.9, 0.0, 0.7, 0.0])
Q_RIGHT = np.array([-0.7, 0.2, 0.0, 0.9, 0.0, 0.7, 0.0])


def _dense_free(world: CollisionWorld, waypoints: np.ndarray, step: float = 0.002) -> bool:
    """Independent check, 2.5x finer than the planner's resolution."""
    for a, b in pairwise(waypoints):
        n = int(np.ceil(np.max(np.abs(b - a)) / step))
        if any(world.in_collision(a + (b - a) * k / n) for k in range(n + 1)):
            return False
    return True


def test_free_move_is_direct(free_world, limits):
    path = Planner(free_world, limits).plan(Q_LEFT, Q_RIGHT)
    assert path.method == "direct"
    np.testing.assert_array_equal(path.waypoints, [Q_LEFT, Q_RIGHT])


@pytest.mark.parametrize("planner", ["RRTConnect", "BITstar"])
def test_detour_around_a_wall_passes_the_gate(robot, safety, limits, timer, planner):
    world = CollisionWorld(robot.copy(), safety, obstacles=[wall_between(robot, Q_LEFT, Q_RIGHT)])
    p = Planner(world, limits, PlannerConfig(planner=planner, timeout_s=2.0))
    assert not p.segment_free(Q_LEFT, Q_RIGHT)
    path = p.plan(Q_LEFT, Q_RIGHT)
    assert path.method == planner and len(path.waypoints) >= 3
    np.testing.assert_array_equal(path.waypoints[[0, -1]], [Q_LEFT, Q_RIGHT])
    assert _dense_free(world, path.waypoints)
    for blend in (False, True):
        check = gate_check(world, Q_LEFT) if blend else None
        traj = timer.time([path.waypoints], blend=blend, check=check)
        approved = approve(traj, world, q_current=Q_LEFT)  # raises GateRefused with the reasons otherwise
        assert approved.report.ok


def test_smoothing_cuts_free_corners_and_blending_beats_stopping(robot, safety, limits, timer, free_world):
    p = Planner(free_world, limits)
    up = np.array([0.0, -0.3, 0.0, 1.3, 0.0, 1.2, 0.0])
    path = np.array([Q_LEFT, up, Q_RIGHT])
    smooth = p.smooth(path)
    np.testing.assert_allclose(smooth[1:3], [up + 0.25 * (Q_LEFT - up), up + 0.25 * (Q_RIGHT - up)])
    stop = timer.time([path])
    blended = timer.time([smooth], blend=True, check=gate_check(free_world, Q_LEFT))
    assert approve(blended, free_world, q_current=Q_LEFT).report.ok
    assert blended.duration_s < 0.85 * stop.duration_s
    with pytest.raises(ValueError, match="fraction"):
        p.smooth(path, fraction=0.7)


def test_smoothing_keeps_corners_it_cannot_cut_safely(robot, safety, limits, timer):
    """Around a wall the detour's corners hug the obstacle: what smoothing returns is still free and passes the
    gate (cuts must clear 5 mm more than the padding)."""
    world = CollisionWorld(robot.copy(), safety, obstacles=[wall_between(robot, Q_LEFT, Q_RIGHT)])
    p = Planner(world, limits)
    smooth = p.smooth(p.plan(Q_LEFT, Q_RIGHT).waypoints)
    assert _dense_free(world, smooth)
    blended = timer.time([smooth], blend=True, check=gate_check(world, Q_LEFT))
    assert approve(blended, world, q_current=Q_LEFT).report.ok


def test_invalid_queries_are_explained(robot, safety, limits):
    block = Primitive("block", "world", "box", (0.3, 0.3, 0.3), pose(robot.tcp_pose(Q_LEFT)[:3, 3]))
    world = CollisionWorld(robot.copy(), safety, obstacles=[block])
    p = Planner(world, limits)
    with pytest.raises(PlanningError, match=r"start configuration is in collision: .*block"):
        p.plan(Q_LEFT, Q_RIGHT)
    outside = Q_RIGHT.copy()
    outside[3] = 4.0
    with pytest.raises(PlanningError, match="goal joint 4"):
        p.plan(Q_RIGHT, outside)


def test_search_failure_gives_up_with_reason(robot, safety, limits):
    """A search budget too small for even one step of the detour (1 ms found one on a quiet machine about one time in
    four): the planner gives up and says what it tried."""
    world = CollisionWorld(robot.copy(), safety, obstacles=[wall_between(robot, Q_LEFT, Q_RIGHT)])
    p = Planner(world, limits, PlannerConfig(planner="RRT", timeout_s=1e-6, attempts=2))
    with pytest.raises(PlanningError, match=r"RRT found no collision-free path in 2 x 1e-06 s"):
        p.plan(Q_LEFT, Q_RIGHT)
