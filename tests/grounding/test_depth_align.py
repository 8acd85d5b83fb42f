"""Depth alignment: recovers the affine map in the predictor's space under outliers; refuses what cannot fit."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.grounding.depth_align import DepthAlignmentError, fit_depth_alignment


def _scene(rng, shape=(60, 80)):
    v, u = np.mgrid[0 : shape[0], 0 : shape[1]]
    return (0.8 + 0.01 * v + 0.002 * u + rng.normal(0, 0.001, shape)).astype(np.float32)


@pytest.mark.parametrize("kind", ["depth", "disparity"])
def test_recovers_scale_and_offset_with_outliers(kind):
    rng = np.random.default_rng(0)
    depth = _scene(rng)
    s_true, b_true = 2.5, -0.4
    x = (1.0 / depth) if kind == "disparity" else depth
    pred = ((x - b_true) / s_true).astype(np.float32)  # metric-space value = s * pred + b
    bad = rng.random(depth.shape) < 0.3  # objects, robot, reflections: 30 % wrong pixels
    pred[bad] = rng.uniform(pred.min(), pred.max(), bad.sum())
    fit = fit_depth_alignment(depth, pred, np.ones(depth.shape, bool), kind)
    assert fit.s == pytest.approx(s_true, rel=0.01)
    assert fit.b == pytest.approx(b_true, abs=0.01 * abs(b_true) + 0.005)
    assert 0.6 < fit.inlier_fraction < 0.8
    aligned = fit.apply(pred)
    assert np.nanmedian(np.abs(aligned[~bad] - depth[~bad])) < 0.002
    assert fit.residual_m < 0.002


def test_fitting_in_the_wrong_space_leaves_a_large_residual():
    rng = np.random.default_rng(1)
    depth = _scene(rng) * 2.0
    disparity = (1.0 / depth).astype(np.float32)
    wrong = fit_depth_alignment(depth, disparity, np.ones(depth.shape, bool), "depth", inlier_rel=0.05)
    right = fit_depth_alignment(depth, disparity, np.ones(depth.shape, bool), "disparity", inlier_rel=0.05)
    assert right.residual_m < 0.001 and right.inlier_fraction == 1.0
    assert wrong.residual_m > 0.01


def test_only_background_pixels_are_used():
    rng = np.random.default_rng(2)
    depth = _scene(rng)
    pred = depth.copy()
    pred[:, :40] += 0.5  # the moved object covers the left half of the prediction
    background = np.zeros(depth.shape, bool)
    background[:, 40:] = True
    fit = fit_depth_alignment(depth, pred, background, "depth")
    assert fit.s == pytest.approx(1.0, abs=0.01) and fit.b == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize(
    ("pred", "match"),
    [(np.full((60, 80), 3.0, np.float32), "constant"), (np.full((60, 80), np.nan, np.float32), "valid background")],
)
def test_refuses_unusable_predictions(pred, match):
    depth = _scene(np.random.default_rng(3))
    with pytest.raises(DepthAlignmentError, match=match):
        fit_depth_alignment(depth, pred, np.ones(depth.shape, bool), "depth")
