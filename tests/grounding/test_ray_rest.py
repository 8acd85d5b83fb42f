"""A model's goal depth off under the object: the goal is set along the camera ray onto its support."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.ray_rest import SINK_TOLERANCE_M, down_to_support, out_of_support, rest_along_ray
from pipeline.grounding.umeyama import Similarity

UP = np.array([0.0, -1.0, -1.0]) / np.sqrt(2.0)  # the camera looks down at the table at 45 deg
ACROSS = np.array([1.0, 0.0, 0.0])
ALONG = np.cross(UP, ACROSS)
TABLE = np.array([0.0, 0.1, 0.8])  # a point of the table, camera frame
SIDE = 0.06


def _cube(centre: np.ndarray) -> np.ndarray:
    """The cube's surface points (its bottom too: what the camera sees is not the point here)."""
    g = np.linspace(-SIDE / 2, SIDE / 2, 13)
    a, b = np.meshgrid(g, g)
    faces = []
    for axis in range(3):
        for side in (-SIDE / 2, SIDE / 2):
            f = np.zeros((a.size, 3))
            f[:, axis] = side
            f[:, [k for k in range(3) if k != axis]] = np.column_stack([a.ravel(), b.ravel()])
            faces.append(f)
    local = np.vstack(faces)
    return centre + local @ np.column_stack([ACROSS, ALONG, UP]).T


def _table(hidden_under: np.ndarray) -> np.ndarray:
    """The table's points the capture sees: all but those under the cube at its start."""
    g = np.arange(-0.3, 0.3, 0.005)
    a, b = np.meshgrid(g, g)
    pts = TABLE + a.ravel()[:, None] * ACROSS + b.ravel()[:, None] * ALONG
    offset = pts - hidden_under
    under = (np.abs(offset @ ACROSS) < SIDE / 2) & (np.abs(offset @ ALONG) < SIDE / 2)
    return pts[~under]


def _start(lift: float = 0.0) -> np.ndarray:
    return TABLE + (SIDE / 2 + lift) * UP


def test_a_goal_too_far_along_the_ray_is_set_back_onto_the_table():
    c0 = _start()
    slide = 0.12 * ACROSS + 0.05 * ALONG
    goal = c0 + slide
    ray = goal / np.linalg.norm(goal)
    off = Similarity(1.0, np.eye(3), slide + 0.02 * ray)  # the goal depth 2 cm long under the object
    rested, shift = rest_along_ray(off, _cube(c0), _table(c0), UP)
    assert abs(shift + 0.02) < 0.002, shift
    assert np.linalg.norm(rested.apply(c0[None])[0] - goal) < 0.002


def test_a_turn_about_the_vertical_is_rested_too():
    c0 = _start()
    turn = Rotation.from_rotvec(np.radians(40.0) * UP).as_matrix()
    goal = c0 + 0.1 * ALONG
    ray = goal / np.linalg.norm(goal)
    off = Similarity(1.0, turn, goal - turn @ c0 - 0.015 * ray)  # 15 mm short
    rested, shift = rest_along_ray(off, _cube(c0), _table(c0), UP)
    assert np.linalg.norm(rested.apply(c0[None])[0] - goal) < 0.002, shift


def test_a_tipped_object_or_one_held_above_the_table_is_left_as_it_is():
    c0 = _start()
    tip = Rotation.from_rotvec(np.radians(90.0) * ACROSS).as_matrix()
    tipped = Similarity(1.0, tip, c0 + 0.1 * ALONG - tip @ c0 + 0.02 * UP)
    kept, shift = rest_along_ray(tipped, _cube(c0), _table(c0), UP)
    assert kept is tipped and shift == 0.0
    held = _start(lift=0.03)
    slid = Similarity(1.0, np.eye(3), 0.1 * ACROSS - 0.005 * UP)  # held 30 mm up at the start, 25 mm at the goal
    kept, shift = rest_along_ray(slid, _cube(held), _table(held), UP)
    assert kept is slid and shift == 0.0


def test_a_goal_over_something_not_level_is_left_as_it_is():
    """Put into a dish, the object stands on no one level the capture shows: its heights beneath spread over
    centimetres, and their median is no support to rest on."""
    c0 = _start()
    goal = c0 + 0.15 * ACROSS
    table = _table(c0)
    offset = table - goal
    across = np.hypot(offset @ ACROSS, offset @ ALONG)
    dish = across < 0.07
    table[dish] += (0.03 * (across[dish] / 0.07) ** 2)[:, None] * UP  # a dish's inside, rising 3 cm to its rim
    ray = goal / np.linalg.norm(goal)
    off = Similarity(1.0, np.eye(3), goal - c0 + 0.015 * ray)
    kept, shift = rest_along_ray(off, _cube(c0), table, UP)
    assert kept is off and shift == 0.0
    _, shift = rest_along_ray(off, _cube(c0), _table(c0), UP)  # the same goal over the table is set down
    assert abs(shift + 0.015) < 0.002, shift


def test_a_correction_under_the_least_gap_is_taken_only_for_a_whole_body():
    c0 = _start()
    goal = c0 + 0.1 * ACROSS
    ray = goal / np.linalg.norm(goal)
    off = Similarity(1.0, np.eye(3), goal - c0 + 0.0015 * ray)  # 1.5 mm long: within a seen cloud's noise
    kept, shift = rest_along_ray(off, _cube(c0), _table(c0), UP)
    assert kept is off and shift == 0.0
    rested, shift = rest_along_ray(off, _cube(c0), _table(c0), UP, min_gap_m=0.0)
    assert np.linalg.norm(rested.apply(c0[None])[0] - goal) < 0.0003, shift


def _lying_can(centre: np.ndarray, radius: float = 0.03, length: float = 0.12) -> np.ndarray:
    """A can lying on its side along ACROSS, its surface points."""
    x, theta = np.meshgrid(np.linspace(-length / 2, length / 2, 25), np.linspace(0.0, 2 * np.pi, 36, endpoint=False))
    ring = np.cos(theta.ravel())[:, None] * UP + np.sin(theta.ravel())[:, None] * ALONG
    return centre + x.ravel()[:, None] * ACROSS + radius * ring


def test_a_body_of_revolution_lying_and_spun_about_its_axis_is_rested_by_its_level_twin():
    """A can lying on its side, slid, comes out spun 25 deg about its own axis (the same body in the same place): as
    it is the motion tilts the vertical 25 deg and is not rested; its twin spun back is upright and is, unless the
    axis it is spun about is read too poorly for the twin to come out level."""
    radius = 0.03
    c0 = TABLE + radius * UP
    slide = 0.1 * ACROSS + 0.04 * ALONG
    goal = c0 + slide
    ray = goal / np.linalg.norm(goal)
    spun = Rotation.from_rotvec(np.radians(25.0) * ACROSS).as_matrix()
    off = Similarity(1.0, spun, c0 - spun @ c0 + slide + 0.02 * ray)  # the goal depth 2 cm long under the can
    can, table = _lying_can(c0, radius), _table(c0)
    assert rest_along_ray(off, can, table, UP)[1] == 0.0
    rested, shift = rest_along_ray(off, can, table, UP, spin=(c0, ACROSS))
    assert abs(shift + 0.02) < 0.002, shift
    assert np.linalg.norm(rested.apply(c0[None])[0] - goal) < 0.002
    assert np.allclose(rested.R, spun)  # the motion's own turn kept: only its place along the ray changes
    misread = Rotation.from_rotvec(np.radians(30.0) * ALONG).apply(ACROSS)  # read 30 deg off: its twin tilts 3 deg
    assert rest_along_ray(off, can, table, UP, spin=(c0, misread))[1] == 0.0


def _heights_above_table(points: np.ndarray) -> np.ndarray:
    return (points - TABLE) @ UP


def test_what_rested_on_the_table_is_taken_down_to_it_and_what_was_held_is_not():
    """Its seen points stop above the table (cut at the support): the bottom is copied down onto it."""
    c0 = _start()
    seen = _cube(c0)
    seen = seen[_heights_above_table(seen) > 0.007]
    whole = down_to_support(seen, _table(c0), UP)
    assert abs(_heights_above_table(whole).min()) < 0.001
    assert np.array_equal(whole[: len(seen)], seen)
    held = _start(lift=0.03)
    seen_held = _cube(held)[_heights_above_table(_cube(held)) > 0.037]
    assert down_to_support(seen_held, _table(held), UP) is seen_held


def test_a_tipped_body_sunk_into_the_table_is_raised_out_along_its_ray_and_a_floating_one_is_left():
    """The model's depth put a cube tipped onto its side 3 cm too far along the ray: its body sinks into the table
    and is raised along the same ray (where the goal image shows it) until it sinks no more than the tolerance."""
    c0 = _start()
    seen = _cube(c0)
    body = down_to_support(seen[_heights_above_table(seen) > 0.007], _table(c0), UP)
    tip = Rotation.from_rotvec(np.radians(90.0) * ACROSS).as_matrix()
    goal = c0 + 0.1 * ALONG
    ray = goal / np.linalg.norm(goal)
    truth = Similarity(1.0, tip, goal - tip @ c0)
    far = Similarity(1.0, tip, truth.t + 0.03 * ray)
    raised = out_of_support(far, body, c0, _table(c0), UP)
    sunk = -_heights_above_table(raised.apply(body)).min()
    assert abs(sunk - SINK_TOLERANCE_M) < 0.0005, sunk
    moved = raised.apply(c0[None])[0] - far.apply(c0[None])[0]
    assert np.linalg.norm(np.cross(moved, ray)) < 1e-6  # along the ray only
    assert np.linalg.norm(raised.apply(c0[None])[0] - goal) < 0.006
    near = Similarity(1.0, tip, truth.t - 0.03 * ray)  # floating: a part it hides may hang lower
    assert out_of_support(near, body, c0, _table(c0), UP) is near
    assert out_of_support(truth, body, c0, _table(c0), UP) is truth
