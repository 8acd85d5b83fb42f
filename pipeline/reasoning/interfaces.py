"""Model-facing steps of stage 1 as interfaces, so Gemini, OpenAI and the offline backends are interchangeable."""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from pipeline.reasoning.types import EditRequest, EditResult, Enhancement, ReflectionRequest, Verdict


class ImageEditor(ABC):
    name: str = "editor"

    @abstractmethod
    def edit(self, request: EditRequest) -> EditResult:
        """A candidate goal image; raises ProviderError (with what the provider said) when there is none."""


class TextVLM(ABC):
    """The text-output VLM: enhances the instruction and judges candidate goals."""

    name: str = "vlm"

    @abstractmethod
    def enhance(self, rgb: np.ndarray, instruction: str) -> Enhancement:
        """A descriptive editing prompt and the phrase naming the object that must move."""

    @abstractmethod
    def reflect(self, request: ReflectionRequest) -> Verdict:
        """Does the synthesis overlay show the instruction carried out? Structured verdict, never free text."""

    def correct(self, prompt: str, problems: list[str]) -> str:
        """The prompt for the next try after the geometric checks refused a candidate (no model call)."""
        return (
            f"{prompt}\nThe previous attempt was rejected: {'; '.join(problems)}. Keep the camera viewpoint, zoom, "
            "framing, lighting and every other object exactly as in the input image."
        )
