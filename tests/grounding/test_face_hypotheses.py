"""Face-frame hypotheses: a box seen on the same faces in both views is recovered however far it turned."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.hypotheses import face_frame, face_hypotheses
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
