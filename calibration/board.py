"""ChArUco board definitions (YAML in configs/boards) and printable images at true scale.

The board frame is OpenCV's: origin at the outer corner of the first square, x along the squares_x side, y along
the squares_y side, z out of the board's back (the printed face looks along -z). Chessboard corners lie at
(i * square, j * square, 0) for i = 1..squares_x-1, j = 1..squares_y-1.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from PIL import Image
from pydantic import Field, ValidationError, model_validator

from drivers.config import StrictModel
from drivers.files import InputFileError, check_output_path, load_yaml

MM_PER_INCH = 25.4


class BoardError(ValueError):
    pass


class CharucoBoardSpec(StrictModel):
    name: str = "charuco"
    squares_x: int = Field(ge=3, le=30)
    squares_y: int = Field(ge=3, le=30)
    square_length_m: float = Field(gt=0.005, lt=0.5)
    marker_length_m: float = Field(gt=0.003, lt=0.5)
    dictionary: str = "DICT_5X5_100"

    @model_validator(mode="after")
    def _consistent(self) -> CharucoBoardSpec:
        if self.marker_length_m >= self.square_length_m:
            raise ValueError(f"marker_length_m {self.marker_length_m} must be below square_length_m")
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"unknown ArUco dictionary {self.dictionary!r} (e.g. DICT_5X5_100, DICT_6X6_250)")
        markers = (self.squares_x * self.squares_y) // 2
        available = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary)).bytesList.shape[0]
        if markers > available:
            raise ValueError(f"the board needs {markers} markers, {self.dictionary} has {available}")
        return self

    @property
    def size_m(self) -> tuple[float, float]:
        return self.squares_x * self.square_length_m, self.squares_y * self.square_length_m

    def board(self) -> cv2.aruco.CharucoBoard:
        dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_length_m, self.marker_length_m, dictionary
        )

    def image(self, px_per_square: int, margin_squares: float = 0.0) -> np.ndarray:
        """Grey board image (uint8), exactly px_per_square pixels per square, with a white margin around it."""
        margin = round(margin_squares * px_per_square)
        w, h = self.squares_x * px_per_square, self.squares_y * px_per_square
        img = self.board().generateImage((w, h), marginSize=0, borderBits=1)
        return cv2.copyMakeBorder(img, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255)


def load_board(path: Path) -> CharucoBoardSpec:
    try:
        data = load_yaml(Path(path), "board definition")
    except InputFileError as e:
        raise BoardError(str(e)) from None
    try:
        return CharucoBoardSpec.model_validate(data)
    except ValidationError as e:
        lines = [f"{path}: {'.'.join(str(p) for p in err['loc'])}: {err['msg']}" for err in e.errors()]
        raise BoardError("invalid board definition:\n  " + "\n  ".join(lines)) from None


def write_printable(spec: CharucoBoardSpec, out: Path, dpi: int = 300, margin_m: float = 0.01) -> tuple[int, int]:
    """Write a PNG or PDF whose physical size is the board's at `dpi` (print at 100 %, no fit-to-page).

    Pixels per square are rounded to an integer, so the true square length is reported back via the returned
    image size; the PDF/PNG resolution is set so 1 square prints as square_length_m. Returns (width, height) px.
    """
    suffix = out.suffix.lower()
    if suffix not in (".png", ".pdf"):
        raise BoardError(f"{out}: the board is written as .png or .pdf")
    try:
        check_output_path(out, "the board image")
    except InputFileError as e:
        raise BoardError(str(e)) from None
    px_per_square = round(spec.square_length_m * 1000.0 / MM_PER_INCH * dpi)
    exact_dpi = px_per_square / (spec.square_length_m * 1000.0 / MM_PER_INCH)  # makes one square exactly true size
    img = spec.image(px_per_square, margin_squares=margin_m / spec.square_length_m)
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(out, resolution=exact_dpi) if suffix == ".pdf" else Image.fromarray(img).save(
        out, dpi=(exact_dpi, exact_dpi)
    )
    return img.shape[1], img.shape[0]
