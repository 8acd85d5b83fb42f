"""Femto Bolt stream choices and conversions that need no device: depth modes, profile selection, colour
decoding, intrinsics/distortion from the SDK's structs, and a sanity check of the intrinsics.

The SDK module is passed in (`sdk`), never imported here, so this file also works against test fakes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from drivers.types import CameraIntrinsics

# Depth modes (Azure Kinect compatible): Y16 resolution and the highest frame rate each supports.
DEPTH_MODES: dict[str, tuple[int, int, int]] = {
    "NFOV_UNBINNED": (640, 576, 30),
    "NFOV_BINNED": (320, 288, 30),
    "WFOV_BINNED": (512, 512, 30),
    "WFOV_UNBINNED": (1024, 1024, 15),
}
COLOUR_FORMATS = ("RGB", "MJPG", "YUYV", "BGR")  # preference order
COLOUR_HFOV_DEG = (70.0, 90.0)  # Femto Bolt colour: 80 deg horizontally


class StreamSelectionError(ValueError):
    pass


@dataclass(frozen=True)
class Profile:
    width: int
    height: int
    fps: int
    format: str
    handle: Any  # the SDK's VideoStreamProfile


def video_profiles(profile_list: Any) -> list[Profile]:
    out = []
    for i in range(profile_list.get_count()):
        p = profile_list.get_stream_profile_by_index(i).as_video_stream_profile()
        out.append(Profile(p.get_width(), p.get_height(), p.get_fps(), p.get_format().name, p))
    return out


def choose_depth(profiles: list[Profile], mode: str, fps: int) -> Profile:
    width, height, max_fps = DEPTH_MODES[mode]
    if fps > max_fps:
        raise StreamSelectionError(f"depth mode {mode} runs at most {max_fps} fps, camera.fps is {fps}")
    for p in profiles:
        if (p.width, p.height, p.fps, p.format) == (width, height, fps, "Y16"):
            return p
    offered = sorted({f"{p.width}x{p.height}@{p.fps} {p.format}" for p in profiles})
    raise StreamSelectionError(
        f"the camera offers no {mode} depth stream ({width}x{height} Y16 @ {fps} fps); offered: {', '.join(offered)}"
    )


def choose_colour(profiles: list[Profile], width: int, height: int, fps: int) -> Profile:
    """The requested size if offered, else the smallest larger one with the same aspect ratio (resized later)."""
    usable = [p for p in profiles if p.fps == fps and p.format in COLOUR_FORMATS]
    fitting = [
        p for p in usable if p.width >= width and p.height >= height and abs(p.width / p.height - width / height) < 0.01
    ]
    if not fitting:
        offered = sorted({f"{p.width}x{p.height}@{p.fps} {p.format}" for p in profiles})
        raise StreamSelectionError(
            f"no colour stream of {width}x{height} or larger with that aspect ratio at {fps} "
            f"fps in {', '.join(COLOUR_FORMATS)}; offered: {', '.join(offered)}"
        )
    return min(fitting, key=lambda p: (p.width * p.height, COLOUR_FORMATS.index(p.format)))


def decode_colour(data: np.ndarray, width: int, height: int, fmt: str) -> np.ndarray:
    """Colour frame bytes -> (H, W, 3) uint8 RGB."""
    buf = np.asarray(data, dtype=np.uint8).ravel()
    if fmt == "RGB":
        return buf.reshape(height, width, 3).copy()
    if fmt == "BGR":
        return cv2.cvtColor(buf.reshape(height, width, 3), cv2.COLOR_BGR2RGB)
    if fmt == "YUYV":
        return cv2.cvtColor(buf.reshape(height, width, 2), cv2.COLOR_YUV2RGB_YUY2)
    if fmt == "MJPG":
        bgr = cv2.imdecode(buf, cv2.IMREAD_COLOR)
        if bgr is None or bgr.shape[:2] != (height, width):
            raise ValueError(f"corrupt MJPG colour frame ({buf.size} bytes)")
        return cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    raise ValueError(f"unsupported colour format {fmt}")


def intrinsics_of(intrinsic: Any, width: int, height: int) -> CameraIntrinsics:
    """SDK OBCameraIntrinsic -> CameraIntrinsics for a width x height image (scaled if reported for another)."""
    K = CameraIntrinsics(
        int(intrinsic.width),
        int(intrinsic.height),
        float(intrinsic.fx),
        float(intrinsic.fy),
        float(intrinsic.cx),
        float(intrinsic.cy),
    )
    return K if (K.width, K.height) == (width, height) else K.resized(width, height)


def distortion_of(distortion: Any) -> np.ndarray:
    """SDK OBCameraDistortion (Brown-Conrady, rational k1..k6) -> OpenCV's (k1, k2, p1, p2, k3, k4, k5, k6)."""
    names = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")
    return np.array([float(getattr(distortion, n, 0.0)) for n in names])


def intrinsics_problems(K: CameraIntrinsics, hfov_range_deg: tuple[float, float] = COLOUR_HFOV_DEG) -> list[str]:
    """Why these colour intrinsics look wrong for a Femto Bolt (empty: plausible)."""
    problems = []
    hfov = math.degrees(2 * math.atan(K.width / 2 / K.fx))
    if not hfov_range_deg[0] <= hfov <= hfov_range_deg[1]:
        problems.append(f"horizontal field of view {hfov:.1f} deg outside {hfov_range_deg} deg")
    if abs(K.fx / K.fy - 1.0) > 0.02:
        problems.append(f"fx/fy = {K.fx / K.fy:.3f}: pixels should be square")
    if abs(K.cx - (K.width - 1) / 2) > 0.1 * K.width or abs(K.cy - (K.height - 1) / 2) > 0.1 * K.height:
        problems.append(f"principal point ({K.cx:.1f}, {K.cy:.1f}) far from the image centre")
    return problems
