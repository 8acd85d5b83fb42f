"""Sweep planning on synthetic clouds: the tool's ends, the strokes' geometry, and every refusal with its reason."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.contact.sweep import SweepConfig, SweepRefused, plan_sweep
from pipeline.contact.tool import ToolError, tool_box, tool_shape
from pipeline.contact.types import ContactConfig
from runtime.run.contact import lowest_safe_tcp_height
from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.robot_model import RobotModel

STEP = 0.004


CAMERA = np.array([1.1, 0.0, 0.8])


def box_points(centre, size, yaw: float = 0.0, faces: str = "seen") -> np.ndarray:
    """Points on a box's faces the camera (at CAMERA) sees, or on its top alone (faces="top"), at its pose."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    centre = np.asarray(centre, dtype=float)
    grids = [np.arange(-a / 2, a / 2 + 1e-9, STEP) for a in size]
    out = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            normal = R[:, axis] * sign
            if (faces == "top" and not (axis == 2 and sign > 0)) or normal @ (CAMERA - centre) <= 0 or normal[2] < -0.5:
                continue
            u, v = (k for k in range(3) if k != axis)
            pts = np.zeros((len(grids[u]) * len(grids[v]), 3))
            pts[:, u] = np.repeat(grids[u], len(grids[v]))
            pts[:, v] = np.tile(grids[v], len(grids[u]))
            pts[:, axis] = sign * size[axis] / 2
            out.append(pts)
    return np.vstack(out) @ R.T + centre


def brush(at=(0.62, 0.2), yaw: float = 0.0) -> np.ndarray:
    """A brush like the sim's: a 50 x 120 x 30 mm head, a 150 mm handle reaching back (-x) 14-42 mm up."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    head = box_points(R @ (0, 0, 0.015) + [*at, 0], (0.05, 0.12, 0.03), yaw)
    handle = box_points(R @ (-0.025 - 0.075, 0, 0.028) + [*at, 0], (0.15, 0.022, 0.028), yaw)
    return np.vstack([head, handle])


def dustpan(at=(0.44, -0.21), yaw: float = np.pi / 2) -> np.ndarray:
    """A dustpan like the sim's: walls (25 mm) and floor, open towards its +x (yaw pi/2: towards +y)."""
    depth, width, h = 0.15, 0.26, 0.025
    parts = [
        box_points((-depth / 2 + 0.003, 0, h / 2), (0.006, width, h)),
        box_points((-0.015, width / 2 - 0.003, h / 2), (depth - 0.03, 0.006, h)),
        box_points((-0.015, -width / 2 + 0.003, h / 2), (depth - 0.03, 0.006, h)),
        box_points((-0.015, 0, 0.001), (depth - 0.03, width - 0.012, 0.002), faces="top"),
    ]
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return np.vstack(parts) @ R.T + [*at, 0.0]


def screws(centre=(0.45, 0.05), spread: float = 0.05, n: int = 6, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.vstack(
        [
            box_points(
                (*(np.asarray(centre) + rng.uniform(-spread, spread, 2)), 0.006),
                (0.045, 0.012, 0.012),
                rng.uniform(0, 3),
            )
            for _ in range(n)
        ]
    )


@pytest.fixture(scope="module")
def robot():
    return RobotModel()


def sweep_plan(robot, group, tool, container, others=None, goal=(0.44, -0.20)):
    scene = container[container[:, 2] > 0.01]
    if others is not None:
        scene = np.vstack([scene, others])
    T = np.eye(4)
    T[:2, 3] = np.asarray(goal) - group[:, :2].mean(axis=0)
    safety = SafetyConfig(padding_m=0.01)
    contact = ContactConfig(min_tcp_height_m=lowest_safe_tcp_height(robot, 0.01), collision_padding_m=0.01)
    plan = plan_sweep(
        group,
        tool,
        container,
        scene,
        T,
        robot,
        contact=contact,
        safety_config=safety,
        viewpoint=np.array([1.1, 0, 0.8]),
    )
    return plan, scene, safety


def test_tool_shape_tells_the_head_from_the_handle():
    for yaw in (0.0, 2.0):
        shape = tool_shape(brush(yaw=yaw))
        head_dir = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        assert shape.axis @ head_dir > 0.99
        assert np.linalg.norm(shape.front[:2] - (np.array([0.62, 0.2]) + 0.025 * head_dir[:2])) < 0.01
        assert shape.head_width_m == pytest.approx(0.12, abs=0.01) and shape.handle_width_m < 0.03
    with pytest.raises(ToolError, match="no working end wider than a handle"):
        tool_shape(box_points((0.5, 0.0, 0.02), (0.2, 0.03, 0.04)))


def test_held_tool_box_is_the_tool_in_its_own_frame(robot):
    shape = tool_shape(brush(yaw=0.6))
    T_grasp = np.eye(4)
    T_grasp[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T_grasp[:3, 3] = [0.55, 0.15, 0.03]
    box = tool_box(shape, T_grasp, tcp_link=robot.tcp_frame, name="brush")
    length, width, height = box.size
    assert length == pytest.approx(0.2, abs=0.012) and width == pytest.approx(0.12, abs=0.012)
    T_base_box = T_grasp @ box.T_link_geom
    assert T_base_box[2, 3] - height / 2 == pytest.approx(0.0, abs=1e-6)  # from the table it lies on


def test_strokes_cover_the_group_and_end_inside_the_dustpan(robot):
    group, tool, container = screws(), brush(), dustpan()
    plan, scene, safety = sweep_plan(robot, group, tool, container)
    assert len(plan.strokes) == SweepConfig().passes * len(plan.lanes_m) and 1 <= len(plan.lanes_m) <= 2
    assert plan.T_contact[2, 2] < -0.95 and abs(plan.T_contact[:3, 1] @ [1.0, 0.0, 0.0]) < 0.35  # across the handle
    cfg = SweepConfig()
    world = CollisionWorld(robot, safety, points=scene, held=plan.held, held_padding_m=cfg.tool_padding_m)
    for stroke in plan.strokes:
        for T, q in ((stroke.T_start, stroke.q_start), (stroke.T_end, stroke.q_end)):
            assert np.allclose(robot.tcp_pose(q), T, atol=1e-3)
            assert not world.in_collision(q, plan.width_m)
            box = T @ plan.held.T_link_geom
            assert box[2, 3] - plan.held.size[2] / 2 == pytest.approx(cfg.clearance_m, abs=1e-3)
    # the head ends over the dustpan's floor (y from -0.285 to -0.135 here), having started behind the screws
    ends = [s.T_end[1, 3] for s in plan.strokes]
    starts = [s.T_start[1, 3] for s in plan.strokes]
    assert all(e < -0.05 for e in ends) and all(s > group[:, 1].max() for s in starts)


@pytest.mark.parametrize(
    ("case", "why"),
    [
        ("dustpan turned away", "opens away from it"),
        ("block in the way", "stand in the head's way"),
        ("brush out of reach", "handle cannot be grasped"),
        ("screws spread wide", "strokes of the"),
    ],
)
def test_sweeps_that_cannot_be_done_are_refused_with_the_reason(robot, case, why):
    group, tool, container, others = screws(), brush(), dustpan(), None
    if case == "dustpan turned away":
        container = dustpan(yaw=-np.pi / 2)
    elif case == "block in the way":
        others = box_points((0.45, -0.06, 0.025), (0.05, 0.05, 0.05))
    elif case == "brush out of reach":
        tool = brush(at=(1.05, 0.5))
    else:
        group = np.vstack([screws((x, 0.08), 0.01, 2) for x in (0.25, 0.5, 0.75)])
    with pytest.raises(SweepRefused, match=why):
        sweep_plan(robot, group, tool, container, others)


def test_a_block_on_a_stand_is_grasped_clear_of_the_stand(robot):
    """The support under an object is found from the scene around it: the fingers stay above the board (seen as
    1 cm cells by the gate), where on the table they would go as deep as the object allows."""
    from pipeline.contact.planner import plan_contacts
    from pipeline.contact.sampling import support_height

    block = box_points((0.45, -0.15, 0.09 + 0.0225), (0.045, 0.045, 0.045))
    board = box_points((0.45, -0.15, 0.09 - 0.0075), (0.12, 0.12, 0.015))
    board = board[np.linalg.norm(board[:, :2] - [0.45, -0.15], axis=1) > 0.04]  # the run's scene loses what is near
    assert support_height(block, board) == pytest.approx(0.09, abs=0.005)
    assert support_height(block - [0, 0, 0.09], np.zeros((0, 3))) == 0.0
    contact = ContactConfig(min_tcp_height_m=lowest_safe_tcp_height(robot, 0.01), collision_padding_m=0.01)
    on_stand = plan_contacts(block, board, np.eye(4), robot, config=contact)
    assert on_stand.ok and on_stand.best.T_contact[2, 3] >= 0.09 + contact.min_tcp_height_m + 0.01 - 1e-6
    on_table = plan_contacts(block - [0, 0, 0.09], np.zeros((0, 3)), np.eye(4), robot, config=contact)
    assert on_table.best.T_contact[2, 3] < on_stand.best.T_contact[2, 3] - 0.09 + 0.005
