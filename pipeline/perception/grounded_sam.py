"""Grounded SAM through transformers: GroundingDINO proposes boxes for a phrase, SAM turns each box into a mask.

Models load with `from_pretrained` from a hub id or a local folder (config: pipeline.grounded_sam). Masks come
back at the input resolution. Overlapping proposals of one object are merged (mask IoU), so that a count of
detections means a count of objects: the reasoning loop treats two as a duplicated target.
"""

from __future__ import annotations

import numpy as np

from pipeline.perception.config import GroundedSamConfig
from pipeline.perception.segmenter import Detection, Segmenter, box_of, check_rgb

DUPLICATE_IOU = 0.7


class GroundedSamSegmenter(Segmenter):
    name = "grounded_sam"

    def __init__(self, config: GroundedSamConfig) -> None:
        import torch
        from transformers import AutoModelForZeroShotObjectDetection, AutoProcessor, SamModel, SamProcessor

        self.config = config
        self.torch = torch
        self.device = torch.device(config.device)
        self.det_processor = AutoProcessor.from_pretrained(config.detector_model)
        self.detector = AutoModelForZeroShotObjectDetection.from_pretrained(config.detector_model).to(self.device)
        self.sam_processor = SamProcessor.from_pretrained(config.sam_model)
        self.sam = SamModel.from_pretrained(config.sam_model).to(self.device)
        self.detector.eval()
        self.sam.eval()

    def segment(self, rgb: np.ndarray, phrase: str, depth_m: np.ndarray | None = None) -> list[Detection]:
        """depth_m is not used: the detector's boxes and SAM's masks come from the image alone."""
        from PIL import Image

        check_rgb(rgb, "grounded_sam")
        h, w = rgb.shape[:2]
        image = Image.fromarray(rgb)
        text = phrase.strip().lower().rstrip(".") + "."
        cfg = self.config
        with self.torch.inference_mode():
            inputs = self.det_processor(images=image, text=text, return_tensors="pt").to(self.device)
            outputs = self.detector(**inputs)
            found = self.det_processor.post_process_grounded_object_detection(
                outputs,
                inputs["input_ids"],
                threshold=cfg.box_threshold,
                text_threshold=cfg.text_threshold,
                target_sizes=[(h, w)],
            )[0]
            boxes = found["boxes"].detach().cpu().float()
            if len(boxes) == 0:
                return []
            boxes[:, 0::2] = boxes[:, 0::2].clamp(0, w - 1)
            boxes[:, 1::2] = boxes[:, 1::2].clamp(0, h - 1)
            sam_in = self.sam_processor(image, input_boxes=[boxes.tolist()], return_tensors="pt").to(self.device)
            sam_out = self.sam(**sam_in, multimask_output=False)
            masks = self.sam_processor.post_process_masks(
                sam_out.pred_masks.cpu(), sam_in["original_sizes"].cpu(), sam_in["reshaped_input_sizes"].cpu()
            )[0]
        masks = masks.reshape(len(boxes), -1, h, w)[:, 0].numpy().astype(bool)
        scores = found["scores"].detach().cpu().float().numpy()
        labels = found.get("text_labels") or found.get("labels") or [phrase] * len(boxes)
        return _distinct(masks, scores, [str(x) for x in labels])


def _distinct(masks: np.ndarray, scores: np.ndarray, labels: list[str]) -> list[Detection]:
    """Best-first detections, dropping empty masks and those overlapping a better one (same object twice)."""
    kept: list[Detection] = []
    for i in np.argsort(-scores):
        m = masks[i]
        if not m.any():
            continue
        if any((m & d.mask).sum() / (m | d.mask).sum() > DUPLICATE_IOU for d in kept):
            continue
        kept.append(Detection(m, float(scores[i]), box_of(m), labels[i]))
    return kept
