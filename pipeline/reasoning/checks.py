"""Cheap geometric checks on a candidate goal image, run before any reflector is asked.

Image editors are known to change the framing (zoom, aspect, shift), drop or duplicate the target, and move
things they were not asked to move. Each check returns readable problems with the numbers; a framing change
can instead be undone by re-registering the candidate onto the initial image (background features + RANSAC).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.config import ChecksConfig
from pipeline.grounding.verify import chromaticity
from pipeline.perception.segmenter import PART_BORDER_PX, Detection, Segmenter, box_of


@dataclass(frozen=True)
class Framing:
    """Affine map initial -> candidate pixels estimated on the background, summarised for people."""

    A: np.ndarray  # 2x3
    max_corner_shift_px: float
    scale_change: float  # max relative deviation of the two axis scales from 1
    inliers: int


def resize_to(rgb: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, list[str]]:
    """Bring a candidate to the initial resolution; a changed aspect ratio is reported (then re-registered)."""
    h, w = shape
    notes = []
    if rgb.shape[:2] != (h, w):
        ch, cw = rgb.shape[:2]
        if abs(cw / ch - w / h) > 0.01:
            notes.append(f"aspect ratio changed: candidate {cw}x{ch}, initial {w}x{h}")
        rgb = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA if cw > w else cv2.INTER_LINEAR)
    return rgb, notes


def estimate_framing(rgb_init: np.ndarray, rgb_cand: np.ndarray, background: np.ndarray) -> Framing | None:
    """Affine initial -> candidate from ORB matches on background pixels; None if too few consistent matches."""
    h, w = background.shape
    g0 = cv2.cvtColor(rgb_init, cv2.COLOR_RGB2GRAY)
    g1 = cv2.cvtColor(rgb_cand, cv2.COLOR_RGB2GRAY)
    if np.abs(g0.astype(np.int16) - g1.astype(np.int16))[background].mean() < 2.0:
        return Framing(np.array([[1.0, 0, 0], [0, 1.0, 0]]), 0.0, 0.0, int(background.sum()))
    orb = cv2.ORB_create(nfeatures=2000, fastThreshold=10)
    m = background.astype(np.uint8) * 255
    k0, d0 = orb.detectAndCompute(g0, m)
    k1, d1 = orb.detectAndCompute(g1, None)
    if d0 is None or d1 is None or len(k0) < 8 or len(k1) < 8:
        return None
    matches = cv2.BFMatcher(cv2.NORM_HAMMING, crossCheck=True).match(d0, d1)
    if len(matches) < 8:
        return None
    p0 = np.float32([k0[x.queryIdx].pt for x in matches])
    p1 = np.float32([k1[x.trainIdx].pt for x in matches])
    A, inl = cv2.estimateAffine2D(p0, p1, method=cv2.RANSAC, ransacReprojThreshold=2.0, maxIters=4000)
    if A is None or int(inl.sum()) < 12:
        return None
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=np.float64)
    moved = corners @ A[:, :2].T + A[:, 2]
    scale = max(abs(np.linalg.norm(A[:, 0]) - 1.0), abs(np.linalg.norm(A[:, 1]) - 1.0))
    return Framing(A, float(np.abs(moved - corners).max()), float(scale), int(inl.sum()))


def reregister(rgb_init: np.ndarray, rgb_cand: np.ndarray, framing: Framing) -> tuple[np.ndarray, float]:
    """The candidate warped into the initial framing; pixels it does not cover keep the initial image.

    Returns the image and the uncovered fraction.
    """
    h, w = rgb_init.shape[:2]
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    warped = cv2.warpAffine(rgb_cand, framing.A, (w, h), flags=flags, borderMode=cv2.BORDER_CONSTANT)
    cover = cv2.warpAffine(np.full(rgb_cand.shape[:2], 255, np.uint8), framing.A, (w, h), flags=flags) > 127
    out = np.where(cover[..., None], warped, rgb_init)
    return out, float(1.0 - cover.mean())


def framing_changed(f: Framing, cfg: ChecksConfig) -> bool:
    return f.max_corner_shift_px > cfg.max_shift_px or f.scale_change > cfg.max_scale_change


def describe_framing(f: Framing) -> str:
    return f"framing changed: corners moved up to {f.max_corner_shift_px:.1f} px, zoom {100 * f.scale_change:.1f} %"


SAME_AREA_RATIO = 2.0  # a region this much larger or smaller than the target was is not the target moved
SAME_COLOUR = 40.0  # mean RGB distance within which a region is of the target's colour (shading, blending)
UNCHANGED_LEVELS = 12.0  # a pixel within this many levels of the first image (blurred) did not change ...
UNCHANGED_SHARE = 0.8  # ... and a region this much of whose pixels off the target's first place did not, was there
OLD_MIN_SHARE = 0.2  # a region this much of which looks as before off the target's first place holds another object
NEW_MIN_SHARE = 0.1  # a region's new part, at least this share of it, is the target (the rest was there before)
NEUTRAL_SATURATION = 40  # of 255: a target less saturated than this is white, gray or black
CHANGED_SHARE = 0.5  # a region found among the changed pixels is one when at least this share of it changed
SAME_CHROMA = 0.06  # ... and its mean chromaticity within this of the target's (a white can in the shade is white)


def colour_change(rgb_a: np.ndarray, rgb_b: np.ndarray) -> np.ndarray:
    """(H, W) the largest channel difference between the two images, each blurred 5x5 (pixel noise, edges)."""
    a = cv2.GaussianBlur(rgb_a, (5, 5), 0).astype(np.int16)
    b = cv2.GaussianBlur(rgb_b, (5, 5), 0).astype(np.int16)
    return np.abs(a - b).max(axis=2)


def unchanged_pixels(rgb_init: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixels of `rgb` that still look as in `rgb_init` (blurred, within UNCHANGED_LEVELS or three
    times the image's median change, whichever is more: an editor redraws the whole image with a little drift)."""
    change = colour_change(rgb_init, rgb)
    return change <= max(UNCHANGED_LEVELS, 3.0 * float(np.median(change)))


def changed_only(rgb_init: np.ndarray, rgb: np.ndarray, mask_init: np.ndarray, still: np.ndarray) -> np.ndarray:
    """`rgb` with every `still` pixel (one that looks as in `rgb_init`) painted one saturated colour, opposite the
    target's hue (green for a neutral target): what the edit changed stands alone. An object put on one it merges
    with (a white can on a scale's white plate, a cube on a bowl read with it as a chest and its lid) is one region
    with it, named by the other; painted over, the other is gone and the moved object is a region of its own. An
    unchanged object enclosed by changed pixels keeps its outline in the paint's colour: regions found in this image
    are the target only where they changed (find_again)."""
    hsv_init = cv2.cvtColor(rgb_init, cv2.COLOR_RGB2HSV_FULL)[mask_init].astype(np.float64)
    paint = np.array([[[85, 255, 255]]], np.uint8)  # green (hue out of 256)
    if len(hsv_init) and np.median(hsv_init[:, 1]) >= NEUTRAL_SATURATION:
        hue = np.angle(np.exp(2j * np.pi * hsv_init[:, 0] / 256).mean()) / (2 * np.pi) * 256
        paint[..., 0] = round(float(hue) + 128) % 256
    out = rgb.copy()
    out[still] = cv2.cvtColor(paint, cv2.COLOR_HSV2RGB_FULL)[0, 0]
    return out


def find_again(
    segmenter: Segmenter,
    rgb: np.ndarray,
    phrase: str,
    rgb_init: np.ndarray,
    mask_init: np.ndarray,
    depth_m: np.ndarray | None = None,
    mask_anchor: np.ndarray | None = None,
) -> tuple[list[Detection], str]:
    """The regions `phrase` names in a later image of the scene (a goal candidate, a capture after execution), and
    how they were found when the phrase alone found none ("" when it did): among the pixels that changed
    (changed_only: the target merged with what it was put on); or, for a part of another colour than its object
    (`mask_anchor`: a lid's box), by the part's own colour in the first image (a lid of another colour shut over its
    box hides the box's top, what is left of the box reads as another kind, and "the lid of the pink chest" names
    nothing). A part is found only on its object: a region away from the anchor is some other thing's (the shut
    chest reads as a block and a small box elsewhere as the chest, 12104)."""
    found = on_anchor(segmenter.segment(rgb, phrase, depth_m), mask_anchor)
    if found:
        return found, ""
    still = unchanged_pixels(rgb_init, rgb)
    found = on_anchor(segmenter.segment(changed_only(rgb_init, rgb, mask_init, still), phrase, depth_m), mask_anchor)
    chroma0 = chromaticity(rgb_init[mask_init]).mean(axis=0)
    found = [  # new there, and of the target's colour in any light (not the table a moved object left uncovered)
        d
        for d in found
        if still[d.mask].mean() <= 1.0 - CHANGED_SHARE
        and np.linalg.norm(chromaticity(rgb[d.mask]).mean(axis=0) - chroma0) <= SAME_CHROMA
    ]
    if found:
        return found, "among the pixels that changed"
    if mask_anchor is None:
        return [], ""
    colour, anchor_colour = segmenter.colours_of(rgb_init, mask_init, mask_anchor)
    if colour is None or colour == anchor_colour:
        return [], ""
    found = on_anchor(segmenter.segment(rgb, colour, depth_m), mask_anchor)
    return found, f"by its own colour, {colour}" if found else ""


def on_anchor(found: list[Detection], mask_anchor: np.ndarray | None) -> list[Detection]:
    """The regions that touch the part's object where it was (`mask_anchor`; all of them without one): a hinged
    part stays on its object."""
    if mask_anchor is None:
        return found
    near = cv2.dilate(mask_anchor.astype(np.uint8), np.ones((2 * PART_BORDER_PX + 1,) * 2, np.uint8)).astype(bool)
    return [d for d in found if (d.mask & near).any()]


def like_the_target(detections: list[Detection], rgb_init: np.ndarray, mask_init: np.ndarray, rgb: np.ndarray):
    """Of the regions a phrase matches in a later image (a goal candidate, the capture after execution), the one
    that is the target: regions that were already there (their pixels off the target's first place unchanged: a
    part of another object, left uncovered when the target was put on it, that now reads as the phrase) are not;
    of the rest, the only one whose area is within SAME_AREA_RATIO of the target's in the initial image and whose
    mean colour is within SAME_COLOUR of its; all of them when none or several are (an editor that left the object
    where it was and drew it again is refused). Each region kept that is too large to be the target alone is cut to
    what is new in it (_new_part)."""
    still = unchanged_pixels(rgb_init, rgb) & ~mask_init
    detections = [d for d in detections if still[d.mask].mean() < UNCHANGED_SHARE] or detections
    area0 = max(int(mask_init.sum()), 1)
    detections = [_new_part(d, still) if d.area_px > SAME_AREA_RATIO * area0 else d for d in detections]
    if len(detections) < 2:
        return detections
    colour0 = rgb_init[mask_init].reshape(-1, 3).astype(np.float64).mean(axis=0)

    def alike(d: Detection) -> bool:
        colour = rgb[d.mask].reshape(-1, 3).astype(np.float64).mean(axis=0)
        return (
            1 / SAME_AREA_RATIO <= d.area_px / area0 <= SAME_AREA_RATIO
            and np.linalg.norm(colour - colour0) <= SAME_COLOUR
        )

    found = [d for d in detections if alike(d)]
    return found if len(found) == 1 else detections


def _new_part(d: Detection, still: np.ndarray) -> Detection:
    """The region less the pixels that look as they did off the target's first place (`still`), its largest piece:
    an object put on or against one of its own colour (a ball on a plate, in a bowl, before a chest of that colour)
    is one colour region with it, and what was there before is the other object. The region as it is when less
    than OLD_MIN_SHARE of it was there before (a few blended edge pixels), or less than NEW_MIN_SHARE is new."""
    if still[d.mask].mean() < OLD_MIN_SHARE:
        return d
    n, pieces, stats, _ = cv2.connectedComponentsWithStats((d.mask & ~still).astype(np.uint8), connectivity=8)
    if n < 2:
        return d
    largest = pieces == 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if largest.sum() < NEW_MIN_SHARE * d.mask.sum():
        return d
    return Detection(largest, d.score, box_of(largest), d.label)


def target_count_problems(detections: list[Detection], target: str) -> list[str]:
    if not detections:
        return [f"target '{target}' missing from the candidate"]
    if len(detections) > 1:
        areas = ", ".join(str(d.area_px) for d in detections)
        return [f"target '{target}' appears {len(detections)} times in the candidate (areas {areas} px)"]
    return []


def background_problems(
    rgb_init: np.ndarray, rgb_goal: np.ndarray, exclude: np.ndarray, cfg: ChecksConfig
) -> list[str]:
    """Regions outside the target masks whose colour changed: other objects moved, appeared or vanished."""
    changed = (colour_change(rgb_init, rgb_goal) > cfg.pixel_change_threshold) & ~exclude
    changed = cv2.morphologyEx(changed.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    n, _, stats, centroids = cv2.connectedComponentsWithStats(changed, connectivity=8)
    limit = cfg.max_changed_blob_frac * changed.size
    out = []
    for i in np.argsort(-stats[1:n, cv2.CC_STAT_AREA])[:3] + 1:
        if stats[i, cv2.CC_STAT_AREA] > limit:
            u, v = centroids[i]
            out.append(
                f"background changed outside the target: {stats[i, cv2.CC_STAT_AREA]} px around (u={u:.0f}, "
                f"v={v:.0f}) (limit {limit:.0f} px): another object moved, appeared or vanished"
            )
    return out


def target_motion_problems(
    rgb_init: np.ndarray, rgb_goal: np.ndarray, mask_init: np.ndarray, mask_goal: np.ndarray, cfg: ChecksConfig
) -> list[str]:
    """The target must look different: same silhouette and same pixels means the editor changed nothing."""
    iou = (mask_init & mask_goal).sum() / max((mask_init | mask_goal).sum(), 1)
    diff = np.abs(rgb_init.astype(np.int16) - rgb_goal.astype(np.int16)).max(axis=2)[mask_init | mask_goal]
    if iou > cfg.max_target_iou and (diff.size == 0 or diff.mean() < 10):
        return [f"target did not change (mask overlap {iou:.2f}, mean colour change {diff.mean():.1f})"]
    return []
