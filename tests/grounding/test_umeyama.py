"""Umeyama similarity and its RANSAC: exact recovery, outliers, degenerate samples."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pipeline.grounding.umeyama import ransac_similarity, umeyama, umeyama_batch


def _random_similarity(rng):
    return rng.uniform(0.5, 2.0), Rotation.random(random_state=rng.integers(1 << 31)).as_matrix(), rng.normal(0, 1, 3)


@pytest.mark.parametrize("seed", range(5))
def test_umeyama_recovers_exact_similarity(seed):
    rng = np.random.default_rng(seed)
    s, R, t = _random_similarity(rng)
    P = rng.normal(0, 0.1, (20, 3))
    fit = umeyama(P, s * P @ R.T + t)
    assert fit.scale == pytest.approx(s, rel=1e-9)
    np.testing.assert_allclose(fit.R, R, atol=1e-9)
    np.testing.assert_allclose(fit.t, t, atol=1e-9)


def test_umeyama_rigid_keeps_unit_scale_and_handles_reflection_case():
    rng = np.random.default_rng(1)
    _, R, t = _random_similarity(rng)
    P = rng.normal(0, 0.1, (4, 3))
    fit = umeyama(P, P @ R.T + t, with_scale=False)
    assert fit.scale == 1.0
    assert np.linalg.det(fit.R) == pytest.approx(1.0)
    np.testing.assert_allclose(fit.R, R, atol=1e-9)


def test_batch_matches_single():
    rng = np.random.default_rng(2)
    src, dst = rng.normal(size=(7, 5, 3)), rng.normal(size=(7, 5, 3))
    s, R, t = umeyama_batch(src, dst)
    for k in range(7):
        one = umeyama(src[k], dst[k])
        assert s[k] == pytest.approx(one.scale)
        np.testing.assert_allclose(R[k], one.R, atol=1e-12)
        np.testing.assert_allclose(t[k], one.t, atol=1e-12)


def test_umeyama_rejects_bad_shapes():
    with pytest.raises(ValueError, match="N>=3"):
        umeyama(np.zeros((2, 3)), np.zeros((2, 3)))


def test_ransac_recovers_motion_with_60_percent_outliers():
    rng = np.random.default_rng(3)
    s, R, t = 1.05, Rotation.from_euler("xyz", [20, -40, 150], degrees=True).as_matrix(), np.array([0.2, -0.1, 0.05])
    P = rng.uniform(-0.05, 0.05, (200, 3))
    Q = s * P @ R.T + t + rng.normal(0, 0.0005, P.shape)
    outliers = rng.random(200) < 0.6
    Q[outliers] = rng.uniform(-0.3, 0.3, (outliers.sum(), 3))
    (best, *_) = ransac_similarity(P, Q, 0.003, iterations=2000, scale_range=(0.8, 1.25))
    assert best.transform.scale == pytest.approx(s, abs=0.01)
    angle = np.degrees(Rotation.from_matrix(best.transform.R @ R.T).magnitude())
    assert angle < 1.0
    assert best.inliers[~outliers].mean() > 0.95
    assert best.inliers[outliers].mean() < 0.05


def test_ransac_refuses_collinear_samples():
    P = np.outer(np.linspace(0, 0.1, 50), [1.0, 0.0, 0.0])
    assert ransac_similarity(P, P + 0.1, 0.003, min_sample_spread_m=0.005) == []
