"""A plate standing on its rim (in a rack): grasped across its thickness at the top, never across its slant, with
the fingers opened for its sway; laid on its face by letting it go on its far edge to tip over (tipping.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from motion.manipulation.phases import place_heights
from pipeline.contact.planner import _open_width, plan_contacts
from pipeline.contact.sampling import grasp_candidates
from pipeline.contact.symmetry import ball_centre, turn_deg
from pipeline.contact.tipping import LEAN_DEG, tip_turn
from pipeline.contact.types import ContactConfig
from safety.geometry import transform_points, turn_about
from safety.robot_model import RobotModel

RADIUS, THICK = 0.07, 0.012


def disc(centre, normal, step: float = 0.004) -> np.ndarray:
    """Points on both faces of a disc (radius RADIUS, thickness THICK) about `normal` through `centre`."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    e1 = np.cross(normal, [0.0, 0.0, 1.0] if abs(normal[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    g = np.arange(-RADIUS, RADIUS + 1e-9, step)
    u, v = np.meshgrid(g, g)
    inside = u**2 + v**2 <= RADIUS**2
    u, v = u[inside], v[inside]
    faces = [np.asarray(centre) + np.outer(u, e1) + np.outer(v, e2) + s * THICK / 2 * normal for s in (-1, 1)]
    return np.vstack(faces)


def normals_of(points: np.ndarray, centre: np.ndarray, normal: np.ndarray) -> np.ndarray:
    side = np.sign((points - centre) @ normal)[:, None]
    return side * np.asarray(normal, float)[None, :]


def test_a_standing_plate_is_grasped_square_to_its_faces_opened_for_its_sway():
    cfg, robot = ContactConfig(), RobotModel()
    for lean_deg in (0.0, 15.0):  # upright, and leaning on the rack's tines
        lean = math.radians(lean_deg)
        centre, normal = np.array([0.45, 0.2, 0.082]), np.array([math.cos(lean), 0.0, math.sin(lean)])
        pts = disc(centre, normal)
        candidates, _ = grasp_candidates(pts, normals_of(pts, centre, normal), cfg, 0.085)
        top = [c for c in candidates if c.approach > 0.9]
        assert top
        for c in top:  # closing along the plate's normal, approaching down its plane: pinched across its thickness
            assert abs(c.T_contact[:3, 1] @ normal) > 0.99 and abs(c.T_contact[:3, 2] @ normal) < 1e-6
            assert c.object_width_m < 2 * THICK
            assert c.sway_m > 0.01  # a 14 cm tall plate's top sways more than the fingers' clearance
            assert _open_width(c, cfg, robot) >= c.object_width_m + 2 * (cfg.finger_clearance_m + 0.01)


def test_a_top_grasp_across_a_narrow_blocks_slant_is_refused_and_a_block_does_not_sway():
    cfg = ContactConfig()
    g = np.linspace(0.0, 1.0, 15)
    x, y, z = (a.ravel() for a in np.meshgrid(0.4 + 0.02 * g, 0.05 * g, 0.06 * g))
    block = np.column_stack([x, y, z])  # 2 x 5 cm, 6 cm tall: not flat, not thin
    candidates, rejected = grasp_candidates(block, np.tile([1.0, 0.0, 0.0], (len(block), 1)), cfg, 0.085)
    top = [c for c in candidates if c.approach > 0.99]
    assert top and rejected["across the object's slant"] > 0
    assert all(c.object_width_m <= 2 * min(t.object_width_m for t in top) for c in top)
    assert all(c.sway_m == 0.0 for c in candidates)


def test_a_plate_laid_on_its_face_by_a_sideways_gripper_is_stood_on_its_far_edge_leaning_to_the_grasp():
    lying = disc([0.5, 0.3, THICK / 2 + 0.02], [0.0, 0.0, 1.0])  # grounded 2 cm high
    T_goal = np.eye(4)  # approach along +x, at the rim on the -x side, closing axis vertical
    T_goal[:3, :3] = np.column_stack([np.cross([0, 0, 1.0], [1.0, 0, 0]), [0, 0, 1.0], [1.0, 0, 0]])
    T_goal[:3, 3] = [0.5 - RADIUS + 0.03, 0.3, THICK / 2 + 0.02]
    tip = tip_turn(T_goal, lying)
    assert tip is not None
    stood = transform_points(tip, lying)
    lowest = stood[np.argmin(stood[:, 2])]
    assert lowest[0] > 0.5 + RADIUS - 0.01 and abs(lowest[2]) < 1e-6  # on the edge opposite the grasp, on the table
    assert math.degrees(math.acos(tip[2, 2])) == pytest.approx(90.0 - LEAN_DEG)  # its face LEAN_DEG off upright
    assert stood.mean(axis=0)[0] < lowest[0]  # leaning back over the grasp side: it falls onto where it lay
    T_set = tip @ T_goal
    assert T_set[2, 2] < -math.cos(math.radians(LEAN_DEG + 1))  # the gripper nearly upright, from above
    # nothing to tip: a gripper from above, or an object that is not flat
    down = np.diag([1.0, -1.0, -1.0, 1.0])
    assert tip_turn(down, lying) is None
    assert tip_turn(T_goal, lying + np.array([0, 0, 1.0]) * lying[:, :1] * 3) is None


def standing_plate_laid_beside() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A plate standing on its rim (points, centre, face normal) and the motion that lays it on its face beside
    where it stood, its top towards the robot: a quarter turn about its near bottom edge, then 17 cm aside."""
    centre, normal = np.array([0.45, 0.2, 0.082]), np.array([1.0, 0.0, 0.0])
    lay = turn_about(np.array([centre[0] - THICK / 2, centre[1], 0.012]), np.array([0.0, 1.0, 0.0]), -math.pi / 2)
    shift = np.eye(4)
    shift[:3, 3] = [0.0, 0.17, -0.012 + THICK / 2]
    return disc(centre, normal), centre, normal, shift @ lay


def test_planning_a_standing_plate_onto_the_table_lets_it_go_on_its_edge_from_above():
    robot = RobotModel()
    pts, _, _, motion = standing_plate_laid_beside()
    cfg = ContactConfig(place_lifts_m=place_heights(0.01), collision_padding_m=0.01)
    result = plan_contacts(pts, np.zeros((0, 3)), motion, robot, config=cfg, viewpoint=np.array([1.1, 0.0, 0.8]))
    assert result.ok, result.reason
    plan = result.best
    assert plan.T_set is not None and plan.T_set[2, 2] < -0.9  # let go from above, not sideways
    assert np.allclose(plan.T_goal, plan.T_motion @ plan.T_contact)  # the goal is still the plate lying
    moved = transform_points(plan.T_motion, pts)
    assert abs(np.ptp(moved[:, 2]) - THICK) < 0.003  # lying flat at the goal


def test_a_plate_seen_face_on_is_no_ball():
    """A plate's face, bowed a little by depth noise, lies nearly on a large sphere: taken for a ball, its grounded
    turn was dropped (a ball's turn shows nothing) and the plate was to be carried upright onto the table."""
    rng = np.random.default_rng(0)
    face = disc([0.45, 0.2, 0.082], [1.0, 0.0, 0.0])[: len(disc([0.45, 0.2, 0.082], [1.0, 0.0, 0.0])) // 2]
    bow = 0.02 * ((face[:, 1] - 0.2) ** 2 + (face[:, 2] - 0.082) ** 2) / RADIUS**2  # 2 cm deep at the rim
    face = face + np.column_stack([bow, np.zeros((len(face), 2))]) + rng.normal(0.0, 0.0005, face.shape)
    assert ball_centre(face) is None
    ball = rng.normal(size=(2000, 3))  # a ball's upper half still is one
    ball[:, 2] = np.abs(ball[:, 2])
    ball = np.array([0.45, 0.2, 0.05]) + 0.03 * ball / np.linalg.norm(ball, axis=1, keepdims=True)
    assert ball_centre(ball) is not None


def test_a_plate_grounded_a_half_turn_off_is_carried_by_the_least_turn():
    """A plate looks the same turned half about its normal: registered so, laying it down would turn the wrist
    half round with the plate held by its rim; the plan lays it down by the quarter turn."""
    robot = RobotModel()
    pts, centre, normal, laid = standing_plate_laid_beside()
    spun = laid @ turn_about(centre, normal, math.pi)  # the same plate on the table, a half turn more
    assert turn_deg(spun, np.eye(4)) > 150
    cfg = ContactConfig(place_lifts_m=place_heights(0.01), collision_padding_m=0.01)
    result = plan_contacts(pts, np.zeros((0, 3)), spun, robot, config=cfg, viewpoint=np.array([1.1, 0.0, 0.8]))
    assert result.ok, result.reason
    assert all(turn_deg(p.T_motion, np.eye(4)) == pytest.approx(90.0, abs=1.0) for p in result.plans)
    moved = transform_points(result.best.T_motion, pts)
    np.testing.assert_allclose(moved.mean(axis=0), transform_points(spun, pts).mean(axis=0), atol=1e-6)
