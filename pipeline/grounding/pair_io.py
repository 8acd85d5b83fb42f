"""PAIR.npz (the `goalvla ground` input) read and checked key by key.

Keys: rgb0 (H, W, 3) uint8, depth0 (H, W) float32 metres with 0 or NaN invalid, mask0 (H, W) bool, rgb1,
depth1 (H, W) float relative prediction, depth1_kind "depth" | "disparity", mask1, K (3, 3); optional anchor0
(H, W) bool: the object the target is hinged to (a lid's box), which stays put.

Checked before use, each refusal a PairFileError naming the file, the key and the problem: the archive and every
member's declared dtype and shape (read from its .npy header, before any array is loaded, so a small compressed
file cannot unpack into gigabytes; images at most the camera's largest mode), then the values: K a pinhole
matrix whose focal lengths give a field of view between 1 and 170 degrees and whose principal point lies near the
image, valid metric depth between MIN_DEPTH_M and MAX_DEPTH_M, a finite relative prediction of sane magnitude.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from drivers.files import InputFileError, read_npz
from drivers.types import CameraIntrinsics
from pipeline.grounding.types import GroundingError, GroundingInput

KEYS = ("rgb0", "depth0", "mask0", "rgb1", "depth1", "depth1_kind", "mask1", "K")
OPTIONAL_KEYS = ("anchor0",)
MAX_SIDE_PX = 3840  # the Femto Bolt's largest colour mode is 3840 x 2160
MAX_PIXELS = 3840 * 2160
MAX_FILE_BYTES = 256 * 2**20
MAX_ARRAYS_BYTES = 256 * 2**20  # all arrays as declared: float64 depths and both images at the largest size fit
MIN_DEPTH_M, MAX_DEPTH_M = 0.01, 20.0  # valid metric depth (0 or NaN: invalid)
MAX_RELATIVE_DEPTH = 1e6  # |depth1|: a relative prediction (depth or disparity) is scale-free but not 1e38
FOV_RANGE_DEG = (1.0, 170.0)
_LAYOUT = {  # key: (dtype kinds, ndim)
    "rgb0": ("u", 3),
    "rgb1": ("u", 3),
    "depth0": ("f", 2),
    "depth1": ("f", 2),
    "mask0": ("b", 2),
    "mask1": ("b", 2),
    "anchor0": ("b", 2),
    "K": ("fiu", 2),
    "depth1_kind": ("US", 0),
}


class PairFileError(InputFileError, GroundingError):
    """PAIR.npz is unusable: names the file, the key and the problem (a GroundingError for `goalvla ground`)."""


def _check_header(key: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    """Refuse a member by its declared dtype and shape, before anything is loaded (ValueError: the problem)."""
    if key not in _LAYOUT:
        raise ValueError(f"unknown key (known: {', '.join(KEYS + OPTIONAL_KEYS)})")
    kinds, ndim = _LAYOUT[key]
    if dtype.kind not in kinds or len(shape) != ndim:
        raise ValueError(f"must be {_describe(key)}, got {dtype} {shape}")
    if key == "K" and shape != (3, 3):
        raise ValueError(f"must be a 3x3 matrix, got shape {shape}")
    if key == "depth1_kind" and dtype.itemsize > 64:
        raise ValueError(f"must be the string 'depth' or 'disparity', got {dtype}")
    if key.startswith("rgb") and shape[2] != 3:
        raise ValueError(f"must be (H, W, 3) uint8, got {dtype} {shape}")
    if ndim >= 2 and key != "K":
        h, w = shape[:2]
        if min(h, w) < 1 or max(h, w) > MAX_SIDE_PX or h * w > MAX_PIXELS:
            raise ValueError(f"image {w}x{h} px: must be 1..{MAX_SIDE_PX} px a side, at most {MAX_PIXELS:,} pixels")


def _describe(key: str) -> str:
    return {
        "u": "(H, W, 3) uint8",
        "f": "(H, W) float32",
        "b": "(H, W) bool",
        "fiu": "a 3x3 numeric matrix",
        "US": "the string 'depth' or 'disparity'",
    }[_LAYOUT[key][0]]


def _intrinsics(K: np.ndarray, width: int, height: int, path: Path) -> CameraIntrinsics:
    K = K.astype(np.float64)
    if not np.all(np.isfinite(K)):
        raise PairFileError(path, "must be finite", "K")
    if not np.allclose(K[2], (0.0, 0.0, 1.0), atol=1e-6) or abs(K[1, 0]) > 1e-6 or abs(K[0, 1]) > 1e-6 * abs(K[0, 0]):
        raise PairFileError(
            path, f"must be a pinhole matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], got {K.tolist()}", "K"
        )
    lo, hi = (math.radians(a) / 2 for a in FOV_RANGE_DEG)
    for name, f, size in (("fx", K[0, 0], width), ("fy", K[1, 1], height)):
        if not size / (2 * math.tan(hi)) <= f <= size / (2 * math.tan(lo)):
            raise PairFileError(
                path,
                f"{name} = {f:.4g} px gives a field of view outside {FOV_RANGE_DEG[0]:g}..{FOV_RANGE_DEG[1]:g} deg "
                f"for {size} px",
                "K",
            )
    for name, c, size in (("cx", K[0, 2], width), ("cy", K[1, 2], height)):
        if not -0.5 * size <= c <= 1.5 * size:
            raise PairFileError(path, f"{name} = {c:.4g} px lies far outside the {size} px image", "K")
    return CameraIntrinsics.from_matrix(K, width, height)


def _depths(arrays: dict[str, np.ndarray], path: Path) -> tuple[np.ndarray, np.ndarray]:
    depth0 = arrays["depth0"].astype(np.float32)
    valid = np.isfinite(depth0) & (depth0 != 0)
    if np.isinf(depth0).any() or np.any(depth0[valid] < 0):
        raise PairFileError(path, "has negative or infinite values (invalid pixels must be 0 or NaN)", "depth0")
    lo, hi = (float(depth0[valid].min()), float(depth0[valid].max())) if valid.any() else (MIN_DEPTH_M, MIN_DEPTH_M)
    if lo < MIN_DEPTH_M or hi > MAX_DEPTH_M:
        raise PairFileError(
            path,
            f"valid depth spans {lo:.4g}..{hi:.4g} m; metric depth must lie in "
            f"{MIN_DEPTH_M}..{MAX_DEPTH_M} m (0 or NaN for invalid pixels)",
            "depth0",
        )
    depth1 = arrays["depth1"]
    if np.isinf(depth1).any() or np.abs(depth1[np.isfinite(depth1)]).max(initial=0.0) > MAX_RELATIVE_DEPTH:
        raise PairFileError(path, f"must be finite (NaN for invalid) with |value| <= {MAX_RELATIVE_DEPTH:g}", "depth1")
    return depth0, depth1.astype(np.float32)


def load_pair(path: Path) -> GroundingInput:
    """Read PAIR.npz; raises PairFileError naming the file and the offending key."""
    path = Path(path)
    try:
        arrays = read_npz(path, "PAIR.npz", MAX_FILE_BYTES, MAX_ARRAYS_BYTES, _check_header)
    except InputFileError as e:
        raise PairFileError(e.file, e.problem, e.key) from None
    missing = [k for k in KEYS if k not in arrays]
    if missing:
        raise PairFileError(path, f"missing key(s) {', '.join(missing)} (need {', '.join(KEYS)})")
    rgb0, kind = arrays["rgb0"], arrays["depth1_kind"].item()
    if isinstance(kind, bytes):
        kind = kind.decode("ascii", errors="replace")
    intrinsics = _intrinsics(arrays["K"], rgb0.shape[1], rgb0.shape[0], path)
    depth0, depth1 = _depths(arrays, path)
    try:
        return GroundingInput(
            rgb0,
            depth0,
            arrays["mask0"],
            arrays["rgb1"],
            depth1,
            kind,
            arrays["mask1"],
            intrinsics,
            arrays.get("anchor0"),
        )
    except GroundingError as e:  # its messages start with the key
        text = str(e)
        key = max((k for k in (*KEYS, *OPTIONAL_KEYS) if text.startswith(k)), key=len, default=None)
        raise PairFileError(path, text.removeprefix(key or "").lstrip(), key) from None
