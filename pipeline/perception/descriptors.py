"""Unit-length descriptor rows, and patch-feature grids sampled at pixels: what every feature backend shares."""

from __future__ import annotations

import numpy as np


def normalise_rows(x: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(x, axis=1, keepdims=True)
    return (x / np.maximum(n, 1e-12)).astype(np.float32)


def sample_bilinear(grid: np.ndarray, pixels: np.ndarray, image_size: tuple[int, int]) -> np.ndarray:
    """Upsample a (h, w, C) patch-feature grid covering an image of image_size = (W, H) at pixels (N, 2).

    Grid cell centres sit at ((i + 0.5) W / w - 0.5) in pixels, consistent with CameraIntrinsics.resized.
    """
    h, w, _ = grid.shape
    W, H = image_size
    gu = (pixels[:, 0] + 0.5) * w / W - 0.5
    gv = (pixels[:, 1] + 0.5) * h / H - 0.5
    gu = np.clip(gu, 0, w - 1)
    gv = np.clip(gv, 0, h - 1)
    u0, v0 = np.floor(gu).astype(int), np.floor(gv).astype(int)
    u1, v1 = np.minimum(u0 + 1, w - 1), np.minimum(v0 + 1, h - 1)
    a, b = (gu - u0)[:, None], (gv - v0)[:, None]
    out = (
        (1 - a) * (1 - b) * grid[v0, u0]
        + a * (1 - b) * grid[v0, u1]
        + (1 - a) * b * grid[v1, u0]
        + a * b * grid[v1, u1]
    )
    return normalise_rows(out)
