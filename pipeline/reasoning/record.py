"""Per-iteration record of stage 1: prompts, raw replies, images, overlays, masks, checks and verdicts.

Written into a folder the caller gives (the run record); without one nothing is written. A folder that already
holds a record is refused rather than mixed with stale files from an earlier run.
"""

from __future__ import annotations

import json
from dataclasses import asdict, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image


class Recorder:
    def __init__(self, folder: str | Path | None) -> None:
        self.folder = Path(folder) if folder is not None else None
        if self.folder is not None:
            if (self.folder / "reasoning.json").exists():
                raise FileExistsError(f"{self.folder}: holds a reasoning record already; give a fresh folder")
            self.folder.mkdir(parents=True, exist_ok=True)

    def _path(self, name: str, iteration: int | None) -> Path | None:
        if self.folder is None:
            return None
        folder = self.folder if iteration is None else self.folder / f"iter_{iteration}"
        folder.mkdir(parents=True, exist_ok=True)
        return folder / name

    def text(self, name: str, text: str, iteration: int | None = None) -> None:
        if (path := self._path(name, iteration)) is not None:
            path.write_text(text)

    def json(self, name: str, data: Any, iteration: int | None = None) -> None:
        if (path := self._path(name, iteration)) is not None:
            path.write_text(json.dumps(_plain(data), indent=2))

    def image(self, name: str, image: np.ndarray, iteration: int | None = None) -> None:
        """RGB uint8 or a bool mask (saved as 0/255), as PNG."""
        if (path := self._path(name, iteration)) is not None:
            data = image.astype(np.uint8) * 255 if image.dtype == bool else image
            Image.fromarray(data).save(path)

    def array(self, name: str, array: np.ndarray, iteration: int | None = None) -> None:
        if (path := self._path(name, iteration)) is not None:
            np.save(path, array)


def _plain(data: Any) -> Any:
    if is_dataclass(data):
        return _plain(asdict(data))
    if isinstance(data, dict):
        return {str(k): _plain(v) for k, v in data.items()}
    if isinstance(data, list | tuple):
        return [_plain(v) for v in data]
    if isinstance(data, np.ndarray):
        return data.tolist() if data.size <= 64 else f"<array {data.dtype} {data.shape}>"
    if isinstance(data, np.generic):
        return data.item()
    return data
