"""PAIR.npz (the `goalvla ground` input) read and checked key by key.

Keys: rgb0 (H, W, 3) uint8, depth0 (H, W) float32 metres with 0 or NaN invalid, mask0 (H, W) bool, rgb1,
depth1 (H, W) float relative prediction, depth1_kind "depth" | "disparity", mask1, K (3, 3); optional anchor0
(H, W) bool: the object the target is hinged to (a lid's box), which stays put.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from drivers.types import CameraIntrinsics
from pipeline.grounding.types import GroundingError, GroundingInput

KEYS = ("rgb0", "depth0", "mask0", "rgb1", "depth1", "depth1_kind", "mask1", "K")


def load_pair(path: Path) -> GroundingInput:
    """Read PAIR.npz; raises GroundingError naming the file and the offending key."""
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except (OSError, ValueError, zipfile.BadZipFile) as e:
        raise GroundingError(f"{path}: cannot read as .npz ({e})") from None
    missing = [k for k in KEYS if k not in arrays]
    if missing:
        raise GroundingError(f"{path}: missing key(s) {', '.join(missing)} (need {', '.join(KEYS)})")
    K = arrays["K"]
    if K.shape != (3, 3) or not np.issubdtype(K.dtype, np.number) or not np.all(np.isfinite(K)):
        raise GroundingError(f"{path}: K must be a finite 3x3 matrix, got {K.dtype} {K.shape}")
    rgb0 = arrays["rgb0"]
    if rgb0.ndim != 3:
        raise GroundingError(f"{path}: rgb0 must be (H, W, 3) uint8, got {rgb0.dtype} {rgb0.shape}")
    kind = arrays["depth1_kind"]
    if kind.shape != () or kind.dtype.kind not in "US":
        raise GroundingError(f"{path}: depth1_kind must be the string 'depth' or 'disparity', got {kind.dtype}")
    for key in ("depth0", "depth1"):
        if arrays[key].dtype not in (np.float32, np.float64):
            raise GroundingError(f"{path}: {key} must be float32, got {arrays[key].dtype}")
    depth0 = arrays["depth0"].astype(np.float32)
    if np.isfinite(depth0).any() and np.nanmin(depth0) < 0:
        raise GroundingError(f"{path}: depth0 has negative values (invalid pixels must be 0 or NaN)")
    try:
        intrinsics = CameraIntrinsics.from_matrix(K, rgb0.shape[1], rgb0.shape[0])
        return GroundingInput(
            rgb0,
            depth0,
            arrays["mask0"],
            arrays["rgb1"],
            arrays["depth1"].astype(np.float32),
            str(kind),
            arrays["mask1"],
            intrinsics,
            arrays.get("anchor0"),
        )
    except GroundingError as e:
        raise GroundingError(f"{path}: {e}") from None
    except ValueError as e:
        raise GroundingError(f"{path}: K: {e}") from None
