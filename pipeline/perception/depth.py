"""Depth estimator interface: relative depth of a single RGB image, tagged with the space it is affine in.

Monocular models predict depth only up to an affine map, and Depth Anything's relative head is affine in
inverse depth; the grounding stage fits the map in that space, so the estimate carries its `kind`.
"""

from __future__ import annotations

import hashlib
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pipeline.perception.segmenter import check_rgb

DepthKind = Literal["depth", "disparity"]


class DepthEstimationError(RuntimeError):
    """No depth could be estimated for this image; the message says why."""


@dataclass(frozen=True)
class RelativeDepth:
    """(H, W) float32 prediction at the input image's resolution; affine in depth or in disparity (`kind`)."""

    values: np.ndarray
    kind: DepthKind

    def __post_init__(self) -> None:
        if self.values.dtype != np.float32 or self.values.ndim != 2:
            got = f"{self.values.dtype} {self.values.shape}"
            raise ValueError(f"RelativeDepth.values must be (H, W) float32, got {got}")
        if self.kind not in ("depth", "disparity"):
            raise ValueError(f"RelativeDepth.kind must be 'depth' or 'disparity', got {self.kind!r}")


class DepthEstimator(ABC):
    name: str = "depth"

    @abstractmethod
    def estimate(self, rgb: np.ndarray) -> RelativeDepth:
        """Relative depth of `rgb`, resized back to its resolution."""


def image_key(rgb: np.ndarray) -> str:
    return hashlib.sha1(np.ascontiguousarray(rgb).tobytes() + str(rgb.shape).encode()).hexdigest()


class OfflineDepthEstimator(DepthEstimator):
    """Depth for images whose depth is known by construction: the offline editor registers each goal it composes.

    There is no way to infer depth from an arbitrary image without a model, so an unknown image is an error
    rather than a guess.
    """

    name = "offline"

    def __init__(self) -> None:
        self._known: dict[str, RelativeDepth] = {}

    def remember(self, rgb: np.ndarray, depth: RelativeDepth) -> None:
        if depth.values.shape != rgb.shape[:2]:
            raise ValueError(f"depth {depth.values.shape} does not match image {rgb.shape[:2]}")
        self._known[image_key(rgb)] = depth

    def estimate(self, rgb: np.ndarray) -> RelativeDepth:
        check_rgb(rgb, "offline depth")
        try:
            return self._known[image_key(rgb)]
        except KeyError:
            raise DepthEstimationError(
                "offline depth: this image was not composed by the offline editor, so its depth is unknown; "
                "configure pipeline.depth: depth_anything for images from a generative editor"
            ) from None
