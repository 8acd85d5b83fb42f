"""Depth Anything V2 through transformers: relative depth of one RGB image, resized back to its resolution.

The relative checkpoints predict a disparity-like quantity (affine in inverse depth); metric checkpoints
(config depth_estimation_type "metric") predict depth. The kind travels with the prediction.
"""

from __future__ import annotations

import numpy as np

from pipeline.perception.config import DepthAnythingConfig
from pipeline.perception.depth import DepthEstimator, RelativeDepth
from pipeline.perception.segmenter import check_rgb


class DepthAnythingEstimator(DepthEstimator):
    name = "depth_anything"

    def __init__(self, config: DepthAnythingConfig) -> None:
        import torch
        from transformers import AutoImageProcessor, AutoModelForDepthEstimation

        self.torch = torch
        self.device = torch.device(config.device)
        self.processor = AutoImageProcessor.from_pretrained(config.model)
        self.model = AutoModelForDepthEstimation.from_pretrained(config.model).to(self.device)
        self.model.eval()
        metric = getattr(self.model.config, "depth_estimation_type", "relative") == "metric"
        self.kind = "depth" if metric else "disparity"

    def estimate(self, rgb: np.ndarray) -> RelativeDepth:
        from PIL import Image

        check_rgb(rgb, "depth_anything")
        h, w = rgb.shape[:2]
        with self.torch.inference_mode():
            inputs = self.processor(images=Image.fromarray(rgb), return_tensors="pt").to(self.device)
            pred = self.model(**inputs).predicted_depth
            full = self.torch.nn.functional.interpolate(pred[:, None].float(), size=(h, w), mode="bilinear")
        return RelativeDepth(full[0, 0].cpu().numpy().astype(np.float32), self.kind)
