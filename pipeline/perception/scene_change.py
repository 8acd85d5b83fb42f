"""What moved between two metric depth images from one camera pose: regions whose depth changed.

Two captures of a scene at rest differ only by the sensor's noise, so a region where the depth changed by more than
a tolerance over more than a small area is something that moved (an object rolled, was nudged, taken away or put
there). Isolated pixels are noise and are removed first; each remaining region is sized in square metres from its
depth (a pixel covers (z/fx)(z/fy)), so the same tolerance holds near and far. Pixels invalid in either image
(NaN) are not compared.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from drivers.types import CameraIntrinsics


@dataclass(frozen=True)
class ChangedRegion:
    """One connected region whose depth changed: its pixels, area, largest change and centre (camera frame, as
    it is in the later image)."""

    mask: np.ndarray  # (H, W) bool
    area_m2: float
    max_change_m: float
    centre_camera: np.ndarray

    def describe(self, T_base_camera: np.ndarray | None = None) -> str:
        """e.g. '6.2 cm2 changed by up to 31 mm at (0.45, -0.12, 0.03) m (base frame)'."""
        if T_base_camera is None:
            p, frame = self.centre_camera, "camera"
        else:
            p, frame = T_base_camera[:3, :3] @ self.centre_camera + T_base_camera[:3, 3], "base"
        where = f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m ({frame} frame)"
        return f"{self.area_m2 * 1e4:.1f} cm2 changed by up to {self.max_change_m * 1000:.0f} mm at {where}"


def depth_changes(
    depth_before: np.ndarray,
    depth_after: np.ndarray,
    intrinsics: CameraIntrinsics,
    *,
    min_change_m: float,
    min_area_m2: float,
    within: np.ndarray | None = None,
) -> list[ChangedRegion]:
    """Regions (largest first) where the depth changed by more than min_change_m over at least min_area_m2;
    within: (H, W) bool, the pixels worth comparing (the workspace: the far floor's noise is no change)."""
    a, b = np.asarray(depth_before, dtype=np.float32), np.asarray(depth_after, dtype=np.float32)
    if a.shape != b.shape:
        raise ValueError(f"depth_changes: depth images of different shapes {a.shape} and {b.shape}")
    both = np.isfinite(a) & np.isfinite(b)
    if within is not None:
        both &= within
    diff = np.where(both, np.abs(b - a), 0.0)
    changed = (diff > min_change_m).astype(np.uint8)
    changed = cv2.morphologyEx(changed, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))  # isolated pixels: noise
    count, labels = cv2.connectedComponents(changed, connectivity=8)
    if count <= 1:
        return []
    z = np.where(both, np.maximum(a, b), 0.0)  # the farther surface: the area the change covers there
    pixel_area = z**2 / (intrinsics.fx * intrinsics.fy)
    areas = np.bincount(labels.ravel(), weights=pixel_area.ravel(), minlength=count)
    points = intrinsics.unproject_depth_image(np.where(both, b, np.nan).astype(np.float32))
    out = []
    for label in np.flatnonzero(areas >= min_area_m2):
        if label == 0:
            continue
        mask = labels == label
        out.append(
            ChangedRegion(
                mask=mask,
                area_m2=float(areas[label]),
                max_change_m=float(diff[mask].max()),
                centre_camera=np.median(points[mask], axis=0),
            )
        )
    return sorted(out, key=lambda r: -r.area_m2)
