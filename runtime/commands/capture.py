"""Write one RGB-D capture to a folder: rgb.png, a colour-mapped depth.png and frame.npz."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from drivers.types import RGBDFrame


def colorize_depth(depth: np.ndarray, near_m: float | None = None, far_m: float | None = None) -> np.ndarray:
    """Depth [m] -> BGR picture (turbo colour map, near = red); invalid (NaN) pixels black."""
    valid = np.isfinite(depth)
    if not valid.any():
        return np.zeros((*depth.shape, 3), np.uint8)
    near = float(np.percentile(depth[valid], 1)) if near_m is None else near_m
    far = float(np.percentile(depth[valid], 99)) if far_m is None else far_m
    scaled = np.clip((far - np.where(valid, depth, far)) / max(far - near, 1e-6), 0, 1)
    bgr = cv2.applyColorMap((scaled * 255).astype(np.uint8), cv2.COLORMAP_TURBO)
    bgr[~valid] = 0
    return bgr


def save_frame(frame: RGBDFrame, out_dir: Path) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / "rgb.png", out_dir / "depth.png", out_dir / "frame.npz"]
    if not cv2.imwrite(str(paths[0]), cv2.cvtColor(frame.rgb, cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {paths[0]}")
    if not cv2.imwrite(str(paths[1]), colorize_depth(frame.depth)):
        raise OSError(f"could not write {paths[1]}")
    T = frame.T_base_camera if frame.T_base_camera is not None else np.full((4, 4), np.nan)
    np.savez_compressed(
        paths[2],
        rgb=frame.rgb,
        depth=frame.depth,
        K=frame.intrinsics.K,
        T_base_camera=T,
        stamp_s=frame.stamp_s,
        frame_id=frame.frame_id,
    )
    return paths
