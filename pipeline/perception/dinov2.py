"""DINOv2 dense features through transformers: patch tokens upsampled (bilinearly) to the image's pixels.

The image is resized so both sides are multiples of the patch size (aspect kept to within one patch) and
normalised with the ImageNet statistics; no centre crop, so the patch grid covers exactly the whole image and
pixel coordinates map onto it the same way as CameraIntrinsics.resized.
"""

from __future__ import annotations

import numpy as np

from pipeline.perception.descriptors import sample_bilinear

IMAGENET_MEAN = np.array([0.485, 0.456, 0.406], dtype=np.float32)
IMAGENET_STD = np.array([0.229, 0.224, 0.225], dtype=np.float32)


class Dinov2Features:
    name = "dinov2"

    def __init__(self, model_id: str = "facebook/dinov2-small", device: str = "cpu", short_side_px: int = 448) -> None:
        import torch
        from transformers import AutoModel

        self.torch = torch
        self.device = torch.device(device)
        self.model = AutoModel.from_pretrained(model_id).to(self.device).eval()
        cfg = self.model.config
        self.patch = int(cfg.patch_size)
        self.skip_tokens = 1 + int(getattr(cfg, "num_register_tokens", 0) or 0)
        self.short_side_px = short_side_px

    def patch_grid(self, rgb: np.ndarray) -> np.ndarray:
        """(h, w, C) patch features covering the whole image."""
        import cv2

        H, W = rgb.shape[:2]
        scale = self.short_side_px / min(H, W)
        h = max(1, round(H * scale / self.patch))
        w = max(1, round(W * scale / self.patch))
        img = cv2.resize(rgb, (w * self.patch, h * self.patch), interpolation=cv2.INTER_AREA)
        x = (img.astype(np.float32) / 255.0 - IMAGENET_MEAN) / IMAGENET_STD
        t = self.torch.from_numpy(x.transpose(2, 0, 1)[None]).to(self.device)
        with self.torch.inference_mode():
            tokens = self.model(pixel_values=t).last_hidden_state[0, self.skip_tokens :]
        return tokens.reshape(h, w, -1).float().cpu().numpy()

    def extract(self, rgb: np.ndarray, pixels: np.ndarray, points: np.ndarray | None = None) -> np.ndarray:
        grid = self.patch_grid(rgb)
        return sample_bilinear(grid, np.asarray(pixels, dtype=np.float64), (rgb.shape[1], rgb.shape[0]))
