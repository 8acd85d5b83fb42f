"""Grounded SAM and Depth Anything backends with tiny random models saved and loaded through from_pretrained."""

from __future__ import annotations

import numpy as np
import pytest
from tiny_transformers import save_tiny_depth_anything, save_tiny_grounding_dino, save_tiny_sam

from pipeline.config import PipelineConfig
from pipeline.perception.config import DepthAnythingConfig, GroundedSamConfig
from pipeline.perception.depth_anything import DepthAnythingEstimator
from pipeline.perception.grounded_sam import DUPLICATE_IOU, GroundedSamSegmenter
from pipeline.reasoning.factory import build_depth, build_segmenter


@pytest.fixture(scope="module")
def tiny_models(tmp_path_factory):
    root = tmp_path_factory.mktemp("tiny_models")
    return {
        "detector": save_tiny_grounding_dino(root / "grounding_dino"),
        "sam": save_tiny_sam(root / "sam"),
        "depth": save_tiny_depth_anything(root / "depth_anything"),
    }


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return np.random.default_rng(1).integers(0, 255, (45, 70, 3), dtype=np.uint8)


def test_grounded_sam_masks_come_back_at_input_resolution(tiny_models, image):
    config = GroundedSamConfig(
        detector_model=str(tiny_models["detector"]),
        sam_model=str(tiny_models["sam"]),
        box_threshold=0.01,
        text_threshold=0.01,
    )
    segmenter = build_segmenter(PipelineConfig(segmenter="grounded_sam", grounded_sam=config))
    assert isinstance(segmenter, GroundedSamSegmenter)
    found = segmenter.segment(image, "the red block")
    assert found, "a near-zero threshold must let the random detector's boxes through"
    for d in found:
        assert d.mask.shape == image.shape[:2] and d.mask.dtype == bool and d.mask.any()
        assert 0.0 <= d.score <= 1.0 and isinstance(d.label, str)
        u0, v0, u1, v1 = d.box
        assert 0 <= u0 <= u1 < image.shape[1] and 0 <= v0 <= v1 < image.shape[0]
    assert [d.score for d in found] == sorted((d.score for d in found), reverse=True)
    for i, a in enumerate(found):
        for b in found[i + 1 :]:
            assert (a.mask & b.mask).sum() / (a.mask | b.mask).sum() <= DUPLICATE_IOU


def test_grounded_sam_high_threshold_finds_nothing(tiny_models, image):
    models = {"detector_model": str(tiny_models["detector"]), "sam_model": str(tiny_models["sam"])}
    low = GroundedSamConfig(**models, box_threshold=0.01, text_threshold=0.01)
    top = max(d.score for d in GroundedSamSegmenter(low).segment(image, "red block"))
    assert top < 1.0, "the random detector saturated; the threshold cannot sit above it"
    config = GroundedSamConfig(**models, box_threshold=(top + 1.0) / 2)  # above every box the detector proposes
    assert GroundedSamSegmenter(config).segment(image, "red block") == []
    with pytest.raises(ValueError, match="uint8"):
        GroundedSamSegmenter(config).segment(image.astype(np.float32), "red block")


def test_depth_anything_relative_prediction_at_input_resolution(tiny_models, image):
    estimator = build_depth(
        PipelineConfig(depth="depth_anything", depth_anything=DepthAnythingConfig(model=str(tiny_models["depth"])))
    )
    assert isinstance(estimator, DepthAnythingEstimator)
    depth = estimator.estimate(image)
    assert depth.kind == "disparity"
    assert depth.values.shape == image.shape[:2] and depth.values.dtype == np.float32
    assert np.isfinite(depth.values).all()
    other = estimator.estimate(image[:30, :50].copy())
    assert other.values.shape == (30, 50)


def test_missing_local_model_is_a_clear_error(tmp_path):
    with pytest.raises(OSError):
        DepthAnythingEstimator(DepthAnythingConfig(model=str(tmp_path / "nothing_here")))
