"""Objects of one colour that touch in the image, told apart by depth.

Two objects of one colour and one saturation that meet in the image (a small blue box just behind a blue pan's
rim) make one colour region. Where one stands in front of the other, the depth jumps all along the line where
they meet; inside one object it jumps only in places (a bowl's near rim in front of its floor, a chest's lid over
its box) and its parts still join where the surface runs on (a bowl's sides). So a region is cut where the depth
steps, and it is several objects when the cut leaves several sizeable pieces.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage

STEP_M = 0.02  # neighbouring pixels this far apart in depth lie on different surfaces
SOLID_KERNEL = np.ones((5, 5), np.uint8)  # a piece that keeps half the least area eroded by this is an object's
# body; a sliver cut off along an edge (a bowl's near rim, a lid's lip) does not


def occlusion_pieces(mask: np.ndarray, depth_m: np.ndarray, min_area: int) -> list[np.ndarray]:
    """The region `mask` cut along depth steps and missing depth into the objects it holds: [mask] when it is one
    object. Pixels on the cut and slivers go to the nearest piece, so the pieces cover the region."""
    z = np.where(np.isfinite(depth_m), depth_m, np.nan)
    step = np.zeros(mask.shape, bool)
    for dz, lo, hi in (
        (np.abs(np.diff(z, axis=0)), (slice(None, -1), slice(None)), (slice(1, None), slice(None))),
        (np.abs(np.diff(z, axis=1)), (slice(None), slice(None, -1)), (slice(None), slice(1, None))),
    ):
        jump = np.nan_to_num(dz, nan=0.0) > STEP_M
        step[lo] |= jump
        step[hi] |= jump
    inner = mask & ~step & np.isfinite(z)  # the sensor drops pixels on the edge of an occlusion too
    n, comp = cv2.connectedComponents(inner.astype(np.uint8), connectivity=4)
    pieces = [k for k in range(1, n) if cv2.erode((comp == k).astype(np.uint8), SOLID_KERNEL).sum() >= min_area / 2]
    if len(pieces) < 2:
        return [mask]
    labels = np.where(np.isin(comp, pieces), comp, 0)
    _, (rows, cols) = ndimage.distance_transform_edt(labels == 0, return_indices=True)
    nearest = labels[rows, cols]
    return [mask & (nearest == k) for k in pieces]
