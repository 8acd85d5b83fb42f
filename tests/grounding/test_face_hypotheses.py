"""Face-frame hypotheses: a box seen on the same faces in both views is recovered however far it turned."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.hypotheses import face_frame, face_hypotheses, footprint_hypotheses
from pipeline.grounding.verify import View


def _box_faces(rng, size=(0.05, 0.065, 0.08), per_face=300):
    """Points and outward normals on three mutually perpendicular faces of a box centred at the origin."""
    half = np.asarray(size) / 2
    pts, nrm = [], []
    for axis in range(3):
        p = rng.uniform(-half, half, (per_face, 3))
        p[:, axis] = half[axis]
        n = np.zeros((per_face, 3))
        n[:, axis] = 1.0
        pts.append(p)
        nrm.append(n)
    return np.concatenate(pts), np.concatenate(nrm)


def _view(points, normals):
    empty = np.zeros((4, 4))
    return View(points, normals, np.zeros_like(points), empty, empty.astype(bool), np.zeros((4, 4, 3)))


@pytest.mark.parametrize("seed", range(4))
def test_face_hypotheses_contain_the_true_motion(seed):
    rng = np.random.default_rng(seed)
    points, normals = _box_faces(rng)
    R0 = Rotation.random(random_state=seed).as_matrix()
    R = Rotation.random(random_state=100 + seed).as_matrix()  # any turn, far beyond a sweep step
    t = rng.normal(0, 0.1, 3)
    centre0 = np.array([0.0, 0.0, 0.6])
    view0 = _view(points @ R0.T + centre0, normals @ R0.T)
    view1 = _view((points @ R0.T + centre0) @ R.T + t, normals @ R0.T @ R.T)
    hypotheses = face_hypotheses(view0, view1)
    assert len(hypotheses) == 24
    angles = [np.degrees(np.arccos(np.clip((np.trace(h.R.T @ R) - 1) / 2, -1, 1))) for h in hypotheses]
    best = hypotheses[int(np.argmin(angles))]
    assert min(angles) < 1.0
    np.testing.assert_allclose(best.t, t, atol=2e-3)


def test_face_frame_needs_two_perpendicular_faces():
    rng = np.random.default_rng(0)
    _, normals = _box_faces(rng)
    one_face = normals[:300]
    assert face_frame(one_face) is None
    frame = face_frame(normals)
    np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-9)


def _bottle(rng, n=4000):
    """A bottle's surface along z (a 6 cm body 14 cm long, a 2.4 cm neck 6 cm long), its base at z = 0."""
    z = rng.uniform(0.0, 0.20, n)
    radius = np.where(z < 0.14, 0.03, 0.012)
    a = rng.uniform(0, 2 * np.pi, n)
    return np.column_stack([radius * np.cos(a), radius * np.sin(a), z])


@pytest.mark.parametrize("seed", range(3))
def test_a_bottle_registered_end_for_end_has_the_true_motion_among_its_twins(seed):
    """A registration that put the bottle's neck where its base goes (the true motion composed with a half turn
    across the axis, and slid along it by a few cm, as a partial view's fit leaves it): one of its end-for-end twins
    is the true motion, up to the spin no image shows, within a degree and a few millimetres."""
    from pipeline.grounding.hypotheses import end_for_end
    from pipeline.grounding.types import SeenSymmetry
    from pipeline.grounding.umeyama import Similarity

    rng = np.random.default_rng(seed)
    lying = Rotation.from_euler("yz", [90.0, rng.uniform(0, 360)], degrees=True).as_matrix()
    at = np.array([0.05, 0.02, 0.7])
    points0 = _bottle(rng) @ lying.T + at
    axis0 = lying[:, 2]
    R_true = Rotation.from_rotvec(rng.uniform(-1.5, 1.5, 3)).as_matrix()
    t_true = np.array([0.1, -0.05, 0.02])
    points1 = points0 @ R_true.T + t_true
    shape = SeenSymmetry("revolution", points0.mean(axis=0), axis=axis0, shape_kind="revolution")
    across = Rotation.from_rotvec(
        np.pi * np.cross(axis0, [0.0, 0.0, 1.0]) / np.linalg.norm(np.cross(axis0, [0, 0, 1.0]))
    )
    c = points0.mean(axis=0)
    H = across.as_matrix()
    wrong = Similarity(1.0, R_true @ H, R_true @ (c - H @ c) + t_true + 0.04 * (R_true @ axis0))
    best = min(
        end_for_end(wrong, shape, points0, points1),
        key=lambda m: (
            np.degrees(np.arccos(np.clip((m.R @ axis0) @ (R_true @ axis0), -1, 1)))
            + 1000 * np.linalg.norm(m.apply(c[None])[0] - (R_true @ c + t_true))
        ),
    )
    assert np.degrees(np.arccos(np.clip((best.R @ axis0) @ (R_true @ axis0), -1, 1))) < 1.0
    ends = np.array([c - 0.08 * axis0, c + 0.08 * axis0])  # the axis' points land where the truth puts them
    np.testing.assert_allclose(best.apply(ends), ends @ R_true.T + t_true, atol=0.005)


@pytest.mark.parametrize("seed", range(3))
def test_footprint_hypotheses_turn_a_box_on_the_table_by_its_outline_alone(seed):
    """A box standing on the table, slid and turned about the vertical: its footprint's rectangle gives the turn
    with no normals at all, from other points of its faces in the goal."""
    rng = np.random.default_rng(seed)
    up = Rotation.from_euler("x", 145, degrees=True).as_matrix() @ [0.0, 0.0, 1.0]  # seen from above at 35 deg
    stand = Rotation.align_vectors([up], [[0.0, 0.0, 1.0]])[0].as_matrix()  # the box's z up
    points, _ = _box_faces(rng)
    yaw0, turn = rng.uniform(0, 360), rng.uniform(-180, 180)
    pose = stand @ Rotation.from_euler("z", yaw0, degrees=True).as_matrix()
    placed = points @ pose.T + [0.0, 0.0, 0.6]
    R = Rotation.from_rotvec(np.radians(turn) * up).as_matrix()
    t = np.cross(up, [1.0, 0.0, 0.0]) * rng.uniform(-0.2, 0.2)  # a slide along the table
    goal_points, _ = _box_faces(rng)  # other points on the same faces
    goal = (goal_points @ pose.T + [0.0, 0.0, 0.6]) @ R.T + t
    hypotheses = footprint_hypotheses(placed, goal, up)
    angles = [np.degrees(np.arccos(np.clip((np.trace(h.R.T @ R) - 1) / 2, -1, 1))) for h in hypotheses]
    assert len(hypotheses) == 4 and min(angles) < 1.0, angles
    best = hypotheses[int(np.argmin(angles))]
    centre = placed.mean(axis=0)
    np.testing.assert_allclose(best.apply(centre[None])[0], R @ centre + t, atol=3e-3)


def test_a_round_footprint_gives_no_turn():
    rng = np.random.default_rng(0)
    a, r = rng.uniform(0, 2 * np.pi, 2000), 0.05 * np.sqrt(rng.random(2000))
    disc = np.column_stack([r * np.cos(a), r * np.sin(a), np.full(2000, 0.6)])
    assert footprint_hypotheses(disc, disc + np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])) == []


def test_a_motion_spun_about_its_axis_keeps_the_axis_and_turns_the_rest():
    """hypotheses.spun: eleven twins, 30 deg apart, each putting the axis's points where the motion puts them and
    turning a point off the axis by its own spin; none for a body with no axis."""
    from pipeline.grounding.hypotheses import spun
    from pipeline.grounding.types import SeenSymmetry
    from pipeline.grounding.umeyama import Similarity

    rng = np.random.default_rng(4)
    motion = Similarity(1.0, Rotation.from_rotvec(rng.uniform(-1.5, 1.5, 3)).as_matrix(), rng.uniform(-0.1, 0.1, 3))
    centre, axis = np.array([0.02, -0.03, 0.7]), np.array([0.0, 0.6, 0.8])
    twins = spun(motion, SeenSymmetry("revolution", centre, axis=axis, shape_kind="revolution"))
    on_axis = np.array([centre - 0.05 * axis, centre + 0.1 * axis])
    off_axis = centre + 0.03 * np.cross(axis, [1.0, 0.0, 0.0])
    assert len(twins) == 11
    turned = []
    for twin in twins:
        np.testing.assert_allclose(twin.apply(on_axis), motion.apply(on_axis), atol=1e-12)
        a, b = (m.apply(off_axis[None])[0] - m.apply(centre[None])[0] for m in (twin, motion))
        turned.append(np.degrees(np.arccos(np.clip(a @ b / (np.linalg.norm(a) * np.linalg.norm(b)), -1, 1))))
    np.testing.assert_allclose(sorted(turned), sorted([30, 60, 90, 120, 150, 180, 150, 120, 90, 60, 30]), atol=1e-6)
    assert spun(motion, SeenSymmetry("none", centre)) == []
