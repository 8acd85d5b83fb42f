"""Settings of the model backends of perception (transformers): which weights, on which device."""

from __future__ import annotations

from pydantic import Field

from drivers.config import StrictModel


class GroundedSamConfig(StrictModel):
    """GroundingDINO proposes boxes for the phrase, SAM turns each box into a mask (transformers)."""

    detector_model: str = Field(default="IDEA-Research/grounding-dino-tiny", description="hub id or local folder")
    sam_model: str = Field(default="facebook/sam-vit-base", description="hub id or local folder")
    box_threshold: float = Field(default=0.35, gt=0, lt=1)
    text_threshold: float = Field(default=0.25, gt=0, lt=1)
    device: str = "cpu"


class DepthAnythingConfig(StrictModel):
    model: str = Field(default="depth-anything/Depth-Anything-V2-Small-hf", description="relative (disparity) head")
    device: str = "cpu"


class Dinov2Config(StrictModel):
    model: str = Field(default="facebook/dinov2-small", description="hub id or local folder")
    device: str = "cpu"
    short_side_px: int = Field(default=448, ge=14, le=2048, description="image short side fed to the model")
