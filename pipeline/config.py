"""Goal-VLA method settings: which backend serves each model-facing step."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from drivers.config import StrictModel


class PipelineConfig(StrictModel):
    editor: Literal["offline"] = "offline"
    vlm: Literal["offline"] = "offline"
    segmenter: Literal["offline"] = "offline"
    depth: Literal["offline"] = "offline"
    features: Literal["offline"] = "offline"
    reflection_iterations: int = Field(default=3, ge=1, le=10)
