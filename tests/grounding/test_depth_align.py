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


def _warped_scene(kind: str, warp: float):
    """A table ramp with a box standing on it (depth jump), predicted by a model with a slow multiplicative warp of
    `warp` across the image and an unknown affine map in its own space; the box is excluded from the fit."""
    rng = np.random.default_rng(4)
    h, w = 120, 160
    v, u = np.mgrid[0:h, 0:w]
    depth = (0.7 + 0.004 * v + rng.normal(0, 0.0005, (h, w))).astype(np.float32)
    box = (np.abs(u - 80) < 12) & (np.abs(v - 60) < 10)
    depth[box] -= 0.06
    x = (1.0 / depth) if kind == "disparity" else depth
    field = np.cos(2 * np.pi * (u + 0.5 * v) / (1.2 * w) + 0.7)
    pred = (0.8 * x * (1.0 + warp * field) + 0.1).astype(np.float32)
    return depth, pred, box


@pytest.mark.parametrize("kind", ["depth", "disparity"])
def test_a_slow_warp_of_the_prediction_is_taken_out(kind):
    depth, pred, box = _warped_scene(kind, 0.03)
    affine = fit_depth_alignment(depth, pred, ~box, kind, warp=False)
    warped = fit_depth_alignment(depth, pred, ~box, kind)
    error = lambda fit: float(np.median(np.abs(fit.apply(pred)[box] - depth[box])))  # noqa: E731
    # a 3 % warp leaves the background off by over a centimetre; taken out, by under 1.5 mm
    assert warped.residual_m < 0.0015 < 0.01 < warped.affine_residual_m
    # under the box too, where the background around it says what it is; what is left is the scale, which a table
    # alone cannot tell from a warp (a slow warp along the table's depth ramp looks like another scale)
    assert error(warped) < min(0.004, error(affine)), (error(warped), error(affine))
    assert 0.005 < warped.warp_max < 0.08 and warped.warp is not None
    assert "warp" not in warped.summary() and warped.summary()["warp_max"] == warped.warp_max


def test_a_correction_larger_than_a_warp_is_not_made():
    depth, pred, box = _warped_scene("depth", 0.0)
    pred = pred * (1.0 + 0.3 * np.cos(np.arange(pred.shape[1]) / 20.0))[None].astype(np.float32)  # 30 % waves
    fit = fit_depth_alignment(depth, pred, ~box, "depth")
    assert fit.warp is None and fit.warp_max > 0.08  # left to the affine map, whose residual then refuses
    assert fit.residual_m > 0.005
