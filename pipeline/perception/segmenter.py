"""Segmenter interface: find the instances a short phrase ("the red block") names in an RGB image.

The reasoning loop needs every instance, not only the best one: zero instances means the target is missing from
a generated goal, two means the editor duplicated it. Backends return all detections above their threshold.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import cv2
import numpy as np


class SegmentationError(RuntimeError):
    """The segmenter could not run on this input (bad image, unusable phrase); the message says which."""


@dataclass(frozen=True)
class Detection:
    """One instance: a full-resolution mask (H, W bool), a score in [0, 1], its box (u0, v0, u1, v1) in pixels."""

    mask: np.ndarray
    score: float
    box: tuple[int, int, int, int]
    label: str

    @property
    def area_px(self) -> int:
        return int(self.mask.sum())

    @property
    def centroid_uv(self) -> tuple[float, float]:
        v, u = np.nonzero(self.mask)
        return float(u.mean()), float(v.mean())


def matches(found: list[Detection]) -> str:
    """What a phrase matched, for error messages: "matches 2 objects: a white box at (312, 170), ..."."""
    if not found:
        return "matches no object"
    where = ", ".join(f"a {d.label} at ({d.centroid_uv[0]:.0f}, {d.centroid_uv[1]:.0f})" for d in found)
    return f"matches {len(found)} object{'s' if len(found) > 1 else ''}: {where}"


def apart_from(found: list[Detection], mask: np.ndarray) -> list[Detection]:
    """The detections that are not mostly the object of `mask` (a reference is not the target it relates to: "put
    the red can on the cube", the can seen as a box is no cube)."""
    return [d for d in found if (d.mask & mask).sum() < 0.5 * d.area_px]


PART_BORDER_PX = 3  # a part and its object's region meet within this many pixels


def attached_to(found: list[Detection], mask_part: np.ndarray) -> list[Detection]:
    """Of several regions an object's phrase matches ("the chest" of "close the chest"), the one a part of it is
    attached to: sharing the most of the part's border, or holding the part itself (a lid of the chest's colour is
    in its region). A chest-like region behind the chest (a bowl half hidden) is not the part's object."""
    if len(found) < 2:
        return found
    kernel = np.ones((2 * PART_BORDER_PX + 1,) * 2, np.uint8)
    near = cv2.dilate(mask_part.astype(np.uint8), kernel).astype(bool)
    contact = [int((d.mask & near).sum()) for d in found]
    best = max(contact)
    return [d for d, c in zip(found, contact, strict=True) if c == best] if best > 0 else found


def grow(mask: np.ndarray, px: int) -> np.ndarray:
    """The mask grown by a disc of `px` pixels (a copy where px <= 0)."""
    if px <= 0:
        return mask.copy()
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * px + 1, 2 * px + 1))
    return cv2.dilate(mask.astype(np.uint8), k).astype(bool)


def box_of(mask: np.ndarray) -> tuple[int, int, int, int]:
    v, u = np.nonzero(mask)
    if u.size == 0:
        raise SegmentationError("box_of: empty mask")
    return int(u.min()), int(v.min()), int(u.max()), int(v.max())


def check_rgb(rgb: np.ndarray, who: str) -> None:
    """ValueError naming `who` unless `rgb` is an (H, W, 3) uint8 image."""
    if not isinstance(rgb, np.ndarray) or rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        got = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise ValueError(f"{who}: expected an (H, W, 3) uint8 RGB image, got {got}")


def check_depth(depth_m: np.ndarray | None, rgb: np.ndarray, who: str) -> None:
    """ValueError naming `who` unless `depth_m` is None or a float (H, W) image the size of `rgb`."""
    if depth_m is None:
        return
    if not isinstance(depth_m, np.ndarray) or depth_m.shape != rgb.shape[:2] or depth_m.dtype.kind != "f":
        got = f"{depth_m.dtype} {depth_m.shape}" if isinstance(depth_m, np.ndarray) else type(depth_m).__name__
        raise ValueError(f"{who}: expected a float depth image of shape {rgb.shape[:2]} (metres), got {got}")


class Segmenter(ABC):
    """Text-prompted instance segmentation."""

    name: str = "segmenter"

    @abstractmethod
    def segment(self, rgb: np.ndarray, phrase: str, depth_m: np.ndarray | None = None) -> list[Detection]:
        """All instances of `phrase`, best first; an empty list when there is none. `depth_m` (metres, aligned with
        `rgb`, NaN unknown), where the image has one, tells touching from overlapping in the image: a lid hinged
        on its box from a thing standing behind the box."""

    def colours_of(self, rgb: np.ndarray, *masks: np.ndarray) -> tuple[str | None, ...]:
        """The colour word a phrase would name the region under each mask by, None where the backend cannot tell (a
        part is then found again by its phrase alone)."""
        return (None,) * len(masks)
