"""The stored hand-eye result: a small YAML file with the pose, when it was made and how good it was."""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Literal

import numpy as np
import yaml
from pydantic import Field, ValidationError, field_validator

from drivers.config import StrictModel
from drivers.files import InputFileError, load_yaml


class CalibrationError(ValueError):
    pass


class HandEyeCalibration(StrictModel):
    """`T` is T_base_camera (eye-to-hand) or T_flange_camera (eye-in-hand), a 4x4 rigid transform [m]."""

    mode: Literal["eye_to_hand", "eye_in_hand"]
    T: tuple[tuple[float, float, float, float], ...]
    created: dt.datetime
    method: str = ""
    poses: int = Field(default=0, ge=0)
    residual_mm: float | None = Field(default=None, ge=0, description="median translation residual")
    residual_deg: float | None = Field(default=None, ge=0, description="median rotation residual")

    @field_validator("T")
    @classmethod
    def _rigid(cls, T: tuple) -> tuple:
        M = np.asarray(T, dtype=np.float64)
        if M.shape != (4, 4) or not np.all(np.isfinite(M)):
            raise ValueError("T must be a finite 4x4 matrix")
        R = M[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0.999:
            raise ValueError("T's rotation block is not a rotation (R R^T != I or det != 1)")
        if not np.allclose(M[3], [0, 0, 0, 1]):
            raise ValueError("T's last row must be 0 0 0 1")
        return T

    @property
    def matrix(self) -> np.ndarray:
        return np.asarray(self.T, dtype=np.float64)

    def age_days(self, now: dt.datetime | None = None) -> float:
        now = now or dt.datetime.now(dt.UTC)
        created = self.created if self.created.tzinfo else self.created.replace(tzinfo=dt.UTC)
        return (now - created).total_seconds() / 86400.0


def load_calibration(path: Path) -> HandEyeCalibration:
    try:
        data = load_yaml(Path(path), "calibration")
    except InputFileError as e:
        hint = "; run `goalvla calibrate hand-eye` first" if not Path(path).exists() else ""
        raise CalibrationError(f"{e}{hint}") from None
    try:
        return HandEyeCalibration.model_validate(data)
    except ValidationError as e:
        lines = [f"{path}: {'.'.join(str(p) for p in err['loc'])}: {err['msg']}" for err in e.errors()]
        raise CalibrationError("invalid calibration:\n  " + "\n  ".join(lines)) from None


def save_calibration(calibration: HandEyeCalibration, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    data = calibration.model_dump(mode="json")
    data["T"] = [list(row) for row in calibration.T]
    path.write_text(yaml.safe_dump(data, sort_keys=False))
