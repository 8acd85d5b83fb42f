"""Where the hand-eye calibration lives and how old it may be."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from drivers.config import StrictModel


class CalibrationConfig(StrictModel):
    mode: Literal["eye_to_hand", "eye_in_hand"] = "eye_to_hand"
    file: Path | None = Field(
        default=None, description="calibration YAML; None on the sim = the simulated camera's true pose"
    )
    max_age_days: float = Field(default=30.0, gt=0, description="older calibrations raise a warning")
