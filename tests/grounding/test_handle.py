"""A standing body with a handle (a mug, a pan) is turned about the vertical by where its handle points."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.handle import handle_hypotheses

ON_TABLE = Rotation.from_euler("x", 145, degrees=True).as_matrix()  # the object's z up, seen from above at 35 deg
UP = ON_TABLE @ [0.0, 0.0, 1.0]


def _mug(rng: np.random.Generator, yaw_deg: float, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A can's wall 8 cm across and 10 cm tall with a bar reaching 4 cm out at its top (its handle, facing up),
    turned by yaw_deg about its axis and standing at `at` (camera frame), the points facing the camera kept."""
    a, z = rng.uniform(0, 2 * np.pi, 5000), rng.uniform(0.0, 0.1, 5000)
    wall = np.column_stack([0.04 * np.cos(a), 0.04 * np.sin(a), z])
    wall_normals = np.column_stack([np.cos(a), np.sin(a), np.zeros(5000)])
    bar = np.column_stack([rng.uniform(0.04, 0.08, 800), rng.uniform(-0.006, 0.006, 800), np.full(800, 0.1)])
    points = np.vstack([wall, bar])
    normals = np.vstack([wall_normals, np.tile([0.0, 0.0, 1.0], (800, 1))])
    R = ON_TABLE @ Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    P, N = points @ R.T + at, normals @ R.T
    facing = np.einsum("ij,ij->i", N, -P) > 0
    return P[facing], N[facing]


@pytest.mark.parametrize("turn_deg", [35.0, 150.0, -100.0])
def test_the_handle_gives_the_turn_about_the_vertical(turn_deg):
    rng = np.random.default_rng(3)
    base = np.array([0.0, 0.05, 0.6])
    slide = 0.1 * np.cross(UP, [1.0, 0.0, 0.0])
    seen0, seen1 = _mug(rng, 20.0, base), _mug(rng, 20.0 + turn_deg, base + slide)
    (motion,) = handle_hypotheses(seen0, seen1, UP)
    turn = np.degrees(Rotation.from_matrix(motion.R).as_rotvec() @ UP)
    assert abs((turn - turn_deg + 180) % 360 - 180) < 5.0, turn
    np.testing.assert_allclose(motion.apply(base[None])[0], base + slide, atol=0.005)


def test_a_body_with_no_handle_gives_no_turn():
    P, N = _mug(np.random.default_rng(4), 0.0, np.array([0.0, 0.05, 0.6]))
    wall = np.abs(N @ UP) < 0.5  # the bar faces up: without it the outline is round
    assert handle_hypotheses((P[wall], N[wall]), (P[wall], N[wall]), UP) == []
    assert len(handle_hypotheses((P, N), (P, N), UP)) == 1
