"""Verification's arithmetic: positions and turns judged against the goal, symmetries taken out first."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.achieved import hidden_by_shape
from pipeline.grounding.compare import Symmetry, compare, object_symmetry, square_footprint_axis


def yaw(deg: float) -> np.ndarray:
    return Rotation.from_euler("z", deg, degrees=True).as_matrix()


CAM = np.eye(3)  # camera frame == base frame in these cases: the base z axis is the camera's
UP = np.array([0.0, 0.0, 1.0])


def judge(goal_R, goal_t, achieved_R, achieved_t, centre, R_base_camera=CAM, symmetry=None):
    """compare() with a 3 cm / 15 deg tolerance."""
    return compare(
        goal_R=goal_R,
        goal_t=goal_t,
        achieved_R=achieved_R,
        achieved_t=achieved_t,
        centre_camera=centre,
        R_base_camera=R_base_camera,
        position_tol_m=0.03,
        rotation_tol_deg=15.0,
        symmetry=symmetry,
    )


def test_reached_goal_passes():
    c = np.array([0.1, 0.0, 0.8])
    v = judge(np.eye(3), np.array([0.2, 0, 0]), np.eye(3), np.array([0.21, 0, 0]), c)
    assert v.ok and v.position_error_m == pytest.approx(0.01)


def test_position_off_by_more_than_the_tolerance_fails_with_the_numbers():
    c = np.zeros(3)
    v = judge(np.eye(3), np.array([0.2, 0, 0]), np.eye(3), np.array([0.15, 0, 0]), c)
    assert not v.ok and "50 mm from the goal (tolerance 30)" in v.reason


def about_centre(R: np.ndarray, c: np.ndarray) -> np.ndarray:
    return c - R @ c


def test_turn_is_judged_only_when_the_goal_turns():
    c = np.array([0.0, 0.0, 0.8])
    free = judge(np.eye(3), np.zeros(3), yaw(40), about_centre(yaw(40), c), c)
    assert free.ok and free.twist_error_deg == pytest.approx(40) and not free.twist_judged
    wrong = judge(yaw(90), about_centre(yaw(90), c), yaw(60), about_centre(yaw(60), c), c)
    assert not wrong.ok and "turned 30.0 deg off" in wrong.reason


def test_turns_a_symmetry_hides_are_not_judged():
    c = np.array([0.0, 0.0, 0.8])
    args = (yaw(90), about_centre(yaw(90), c), yaw(20), about_centre(yaw(20), c), c)
    assert not judge(*args).ok
    can = judge(
        *args, symmetry=Symmetry(c, np.array([0.0, 0.0, 1.0]))
    )  # upright: its turn about the vertical is unseen
    assert can.ok and can.twist_error_deg == pytest.approx(0.0, abs=1e-6)
    ball = judge(*args, symmetry=Symmetry(c, None))
    assert ball.ok and not ball.twist_judged and ball.symmetry == "ball"


def test_a_lying_bottle_stood_up_is_judged_on_its_tilt_not_its_spin():
    c = np.array([0.0, 0.0, 0.8])
    axis = np.array([1.0, 0.0, 0.0])  # the bottle lies along x
    stand = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    spun = stand @ Rotation.from_rotvec(np.radians(40) * axis).as_matrix()  # the same, turned about its own axis
    bottle = Symmetry(c, axis)
    ok = judge(stand, about_centre(stand, c), spun, about_centre(spun, c), c, symmetry=bottle)
    assert ok.ok and ok.tilt_error_deg == pytest.approx(0.0, abs=1e-6)
    assert not judge(stand, about_centre(stand, c), spun, about_centre(spun, c), c).ok
    half = Rotation.from_euler("y", 60, degrees=True).as_matrix()
    short = judge(stand, about_centre(stand, c), half, about_centre(half, c), c, symmetry=bottle)
    assert not short.ok and "tilted 30.0 deg" in short.reason


def test_object_symmetry_finds_a_ball_an_upright_can_and_no_box():
    rng = np.random.default_rng(0)
    eye = np.zeros(3)  # camera frame: the camera at the origin looking along +z

    def seen(points: np.ndarray, centre: np.ndarray) -> np.ndarray:
        """The points of a convex body facing the eye, with 0.8 mm depth-like noise."""
        front = points[np.einsum("ij,ij->i", points - centre, eye - points) > 0]
        return front + rng.normal(0, 0.0008, front.shape)

    ball_centre = np.array([0.05, 0.02, 0.8])
    ball = ball_centre + 0.032 * Rotation.random(4000, random_state=1).apply([1.0, 0.0, 0.0])
    round_ = object_symmetry(seen(ball, ball_centre))
    assert round_ is not None and round_.axis is None and np.linalg.norm(round_.centre - ball_centre) < 0.004
    theta, h = rng.uniform(0, 2 * np.pi, 3000), rng.uniform(-0.055, 0.055, 3000)
    can_centre = np.array([-0.1, 0.0, 0.9])
    can = can_centre + np.column_stack([0.03 * np.cos(theta), h, 0.03 * np.sin(theta)])  # upright: along y
    upright = object_symmetry(seen(can, can_centre))
    assert upright is not None and abs(upright.axis[1]) > 0.99
    assert np.linalg.norm((upright.centre - can_centre)[[0, 2]]) < 0.003
    theta, x = rng.uniform(0, 2 * np.pi, 3000), rng.uniform(-0.09, 0.09, 3000)
    bottle_centre = np.array([0.05, 0.1, 0.85])
    bottle = bottle_centre + np.column_stack([x, 0.03 * np.cos(theta), 0.03 * np.sin(theta)])  # lying along x
    lying = object_symmetry(seen(bottle, bottle_centre))
    assert lying is not None and lying.axis is not None and abs(lying.axis[0]) > 0.99  # a cylinder, not a ball
    u, v = rng.uniform(-0.025, 0.025, (2, 3000))
    half = np.full_like(u, 0.025)
    faces = np.concatenate(
        [np.column_stack([u, v, half])]
        + [np.column_stack([s * half, u, v]) for s in (1, -1)]
        + [np.column_stack([u, s * half, v]) for s in (1, -1)]
    )
    cube_centre = np.array([0.0, 0.1, 0.7])
    cube = Rotation.from_euler("xyz", [30, 20, 10], degrees=True).apply(faces) + cube_centre
    assert object_symmetry(seen(cube, cube_centre)) is None


def test_tilt_is_judged_when_the_goal_tilts_in_the_base_frame():
    c = np.array([0.0, 0.0, 0.8])
    tilt = Rotation.from_euler("x", 90, degrees=True).as_matrix()
    half = Rotation.from_euler("x", 60, degrees=True).as_matrix()
    v = judge(tilt, about_centre(tilt, c), half, about_centre(half, c), c)
    assert not v.ok and "tilted 30.0 deg" in v.reason
    unasked = judge(np.eye(3), np.zeros(3), tilt, about_centre(tilt, c), c)
    assert unasked.ok and unasked.tilt_error_deg == pytest.approx(90)  # reported, not judged
    # the same camera-frame rotation is a pure turn about the base vertical when camera x is the base vertical
    R_base_camera = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    v = judge(tilt, about_centre(tilt, c), half, about_centre(half, c), c, R_base_camera)
    assert not v.ok and "turned 30.0 deg" in v.reason and v.tilt_error_deg == pytest.approx(0, abs=1e-6)


def test_a_can_stood_up_on_its_other_end_is_stood_up_and_a_bottle_is_not():
    c = np.array([0.0, 0.0, 0.8])
    axis = np.array([1.0, 0.0, 0.0])  # lying along x
    stand = Rotation.from_euler("y", 90, degrees=True).as_matrix()
    other_end = Rotation.from_euler("y", -90, degrees=True).as_matrix()  # stood on the end the goal has on top
    can = judge(
        stand, about_centre(stand, c), other_end, about_centre(other_end, c), c, symmetry=Symmetry(c, axis, True)
    )
    assert can.ok and can.tilt_error_deg == pytest.approx(0.0, abs=1e-6)
    assert can.symmetry == "revolution_ends_alike"
    bottle = judge(stand, about_centre(stand, c), other_end, about_centre(other_end, c), c, symmetry=Symmetry(c, axis))
    assert not bottle.ok and "tilted 180.0 deg" in bottle.reason  # upside down: its neck shows it
    short = Rotation.from_euler("y", 60, degrees=True).as_matrix()  # the end flip hides no part turn
    half_way = judge(stand, about_centre(stand, c), short, about_centre(short, c), c, symmetry=Symmetry(c, axis, True))
    assert not half_way.ok and "tilted 30.0 deg" in half_way.reason


def lying_body(radius_at, length: float, yaw_deg: float, n: int = 5000, seed: int = 3) -> np.ndarray:
    """The upper half a camera above sees of a body of revolution lying on the table along yaw_deg, its radius
    radius_at(s) at s in [0, length] along its axis, with 0.8 mm depth-like noise (base frame)."""
    rng = np.random.default_rng(seed)
    s, a = rng.uniform(0, length, n), rng.uniform(0.05 * np.pi, 0.95 * np.pi, n)
    r = radius_at(s)
    yaw_ = np.radians(yaw_deg)
    along, across = np.array([np.cos(yaw_), np.sin(yaw_), 0.0]), np.array([-np.sin(yaw_), np.cos(yaw_), 0.0])
    points = (
        np.array([0.45, 0.1, 0.0])
        + np.outer(s - length / 2, along)
        + np.outer(r * np.cos(a), across)
        + np.outer(r * np.sin(a), [0.0, 0.0, 1.0])
    )
    return points + rng.normal(0, 0.0008, (n, 3))


@pytest.mark.parametrize(("radius", "length"), [(0.021, 0.116), (0.031, 0.091), (0.027, 0.12)])
def test_a_can_looks_the_same_end_for_end(radius, length):
    can = object_symmetry(lying_body(lambda s: np.full_like(s, radius), length, 37.0))
    assert can is not None and can.axis is not None and can.ends_alike


@pytest.mark.parametrize(("radius", "length"), [(0.027, 0.19), (0.032, 0.216)])
def test_a_bottle_does_not_look_the_same_end_for_end(radius, length):
    def bottle(s: np.ndarray) -> np.ndarray:  # the sim's bottle: its body 70 % of its length, then a neck
        return np.where(s < 0.7 * length, radius, 0.4 * radius)

    seen = object_symmetry(lying_body(bottle, length, -20.0))
    assert seen is None or not seen.ends_alike


def box_top_and_sides(sides_m, yaw_deg: float, centre=(0.1, 0.0, 0.8), step_m: float = 0.002) -> np.ndarray:
    """A box's top face and two of its sides (camera frame == base frame, z up), turned by yaw about z."""
    a, b, h = sides_m

    def span(low: float, high: float) -> np.ndarray:
        return np.linspace(low, high, int((high - low) / step_m) + 1)  # both edges: the outline is the box's

    u, v = np.meshgrid(span(-a / 2, a / 2), span(-b / 2, b / 2))
    top = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, h)])
    w, z = np.meshgrid(span(-a / 2, a / 2), span(0.0, h))
    front = np.column_stack([w.ravel(), np.full(w.size, -b / 2), z.ravel()])
    q, z = np.meshgrid(span(-b / 2, b / 2), span(0.0, h))
    side = np.column_stack([np.full(q.size, a / 2), q.ravel(), z.ravel()])
    return np.vstack([top, front, side]) @ yaw(yaw_deg).T + np.asarray(centre)


def test_a_box_on_a_square_footprint_is_told_from_an_oblong_one_and_a_can():
    up = np.array([0.0, 0.0, 1.0])
    assert square_footprint_axis(box_top_and_sides((0.060, 0.056, 0.044), 37.0), up) is not None
    assert square_footprint_axis(box_top_and_sides((0.060, 0.048, 0.044), 37.0), up) is None
    angle, height = np.meshgrid(np.linspace(0, 2 * np.pi, 120), np.linspace(0, 0.1, 30))
    can = np.column_stack([0.03 * np.cos(angle.ravel()), 0.03 * np.sin(angle.ravel()), height.ravel()])
    assert square_footprint_axis(can, up) is None  # a disc fills pi/4 of its square


def test_the_turns_a_box_shows_are_told_by_its_equal_sides():
    """A cube hides 24 turns, a box on a square footprint 8, an oblong one its 4 half turns; a can is no box; a box
    whose top is partly hidden (its faces no longer tell it), its square footprint's quarter turns."""
    assert len(hidden_by_shape(box_top_and_sides((0.05, 0.05, 0.05), 37.0), UP).turns) == 24
    assert len(hidden_by_shape(box_top_and_sides((0.060, 0.056, 0.044), 37.0), UP).turns) == 8
    assert len(hidden_by_shape(box_top_and_sides((0.080, 0.050, 0.030), 37.0), UP).turns) == 4
    angle, height = np.meshgrid(np.linspace(0, 2 * np.pi, 120), np.linspace(0, 0.1, 30))
    can = np.column_stack([0.03 * np.cos(angle.ravel()), 0.03 * np.sin(angle.ravel()), height.ravel()])
    assert hidden_by_shape(can, UP) is None or hidden_by_shape(can, UP).turns is None
    box = box_top_and_sides((0.060, 0.058, 0.044), 0.0) - [0.1, 0.0, 0.8]
    hidden = (box[:, 2] > 0.043) & (box[:, 0] + box[:, 1] > 0.02)  # a corner of its top hidden: no rectangle
    assert len(hidden_by_shape(box[~hidden] + [0.1, 0.0, 0.8], UP).turns) == 4  # its square footprint's, about z


def _box_twin(goal: np.ndarray, achieved: np.ndarray, sides_m) -> object:
    """The verdict on a box turned by `achieved` (about its middle) against a goal turning it by `goal`."""
    points = box_top_and_sides(sides_m, 0.0)
    symmetry = hidden_by_shape(points, UP)
    c = symmetry.centre
    return judge(goal, about_centre(goal, c), achieved, about_centre(achieved, c), c, symmetry=symmetry)


def test_a_turn_a_box_hides_is_not_held_against_it():
    """Turned by 60 deg, a box on a square footprint registered turned by 150 (or -30) is where its goal puts it
    (within the 1-2 deg its faces are found to), an oblong one by 240; a cube tipped onto another face stands as
    well as one turned. 30 deg short of any is a wrong turn, and so is an oblong box's quarter turn or a square
    box left standing where its goal tips it."""
    square, oblong, cube = (0.060, 0.056, 0.044), (0.080, 0.050, 0.030), (0.05, 0.05, 0.05)
    tipped = yaw(60) @ Rotation.from_euler("x", 90, degrees=True).as_matrix()
    for goal, achieved, sides in (
        (yaw(60), yaw(150), square),
        (yaw(60), yaw(-30), square),
        (yaw(60), yaw(240), oblong),
        (tipped, yaw(60), cube),
    ):
        v = _box_twin(goal, achieved, sides)
        assert v.ok and v.twist_error_deg < 3 and v.tilt_error_deg < 3 and v.symmetry == "box", v.reason
    for goal, achieved, sides in ((yaw(60), yaw(30), square), (yaw(60), yaw(150), oblong), (tipped, yaw(60), square)):
        v = _box_twin(goal, achieved, sides)
        assert not v.ok and "deg off" in v.reason, v.reason
