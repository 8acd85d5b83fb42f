"""Which kind of the simulator's objects a colour region is, from its silhouette and what lies inside it.

Each kind gets a score in [0, 1] from a few cues measured on the region, each cue a soft interval (1 inside,
falling to 0 within a margin): how well an ellipse fits (a ball, a plate, a bowl seen from above), elongation and
the width profile along the long axis (a bottle's neck, a pan's handle), how many corners the outline has (a
block's polygon against a can's rounded ends), the density of edges inside it (the rim and inner walls of a bowl,
a pan or an open box against the smooth face of a ball or a plate), and a light neutral plate on a base (a
scale). A region is of the kind that scores best; the scores also rank regions when a phrase names a colour.
The intervals come from the sim's renders of each kind over its size range, views across the reach, and shading.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.perception.colour_regions import hsv

SPECK_AREA_FRAC = 8e-4  # a screw's region at most this share of the image (the smallest block is above 9e-4)
PLATE_MAX_SATURATION = 0.025  # a scale's weighing plate is neutral light gray (a pale pink face washed out by the light
# keeps a tint of 0.03-0.06) ...
PLATE_MIN_VALUE = 0.4  # ... and not dark, in the light or in a shadow (where its value falls to about 0.55)
# a neutral scale: its plate and its base are one neutral region, told apart from a white object by a base of a
# darker shade: a white box's or chest's shaded faces keep at least 0.45 of its lit top's value in the sim's
# light, a gray base under a light plate at most 0.35
TWO_TONE_MAX_RATIO = 0.38
# a white scale in the light has its plate and base both clipped white: it is told by the plate's rim (edges inside,
# as many as an open chest's) around a core that stays lit (little of the region's core in shade, where an open
# chest's inner walls and floor, and a shut one's tall sides, are); the core is the region eroded by CORE_SHARE of
# its smaller extent, a pixel in shade below SHADE_OF_TOP of the region's 90th-percentile value
CORE_SHARE, SHADE_OF_TOP = 0.15, 0.8
BOX_MAX_ELONGATION = 2.6  # a block's side seen square-on: the sim's boxes are up to 2.5 times as tall as wide
# a platform or scale is about as deep as it is wide: seen from the camera at most 1.75 times as long as wide (212
# seen), a lying bottle or can 2-6 (a light one's lit faces read as a neutral plate on top)
PLATFORM_MAX_ELONGATION = 2.2
RESEMBLES = 0.9  # a kind that only resembles an older one (dustpan, rack, stand) scores at most this
NOTCH_SHARE = 0.15  # notches narrower than this share of a region's smaller extent are closed (a rack's tines)
# shading, on the brightest channel: a pixel is level when its 3x3 neighbourhood varies by at most LEVEL_STEP of its
# value (or LEVEL_MIN_LEVELS of 255: quantisation, a face's fine texture), on a ramp when it is not and its 5x5
# neighbourhood varies RAMP_RATIO times as much (shading that keeps changing: a curved surface; an edge between two
# faces is a step, as large over 3x3 as over 5x5). Clipped pixels (CLIPPED of 255 and up) say nothing, nor does a
# region too dark to read shading from (median below DARK_VALUE: a black can is level within quantisation).
LEVEL_STEP, LEVEL_MIN_LEVELS, RAMP_RATIO = 0.02, 2, 1.5
CLIPPED, DARK_VALUE = 250, 60
MIN_UNCLIPPED = 0.5  # the shading is read when at least this share of the region's inside is unclipped ...
# ... or, from as little as PARTLY_UNCLIPPED of it, when what is left shows a curved surface: a light can lying in the
# light is clipped along its side but for a band that ramps (a box's faces do not), while a level remainder says
# nothing (a standing can whose side is clipped shows its level top); such a remainder is read from twice
# MIN_SHADED_PX pixels, since the clip's blurred edge ramps too and makes most of a small one (a pale block's)
PARTLY_UNCLIPPED, CURVED_RAMP = 0.15, 0.35
MIN_SHADED_PX = 40
# relief: the region's core (eroded by RELIEF_CORE_SHARE of its smaller extent) against the surface through its
# outline (a band RELIEF_BAND_PX wide inside it, less its outermost pixel, where depth bleeds across the boundary);
# inverse depth is affine in the pixel coordinates on a plane, so the surface is fitted to it. Hollow objects' cores
# lie 27-95 mm behind (bowls, pans, open boxes), plates' 0-5 mm before, blocks', cans' and balls' 0-40 mm before
RELIEF_CORE_SHARE, RELIEF_BAND_PX, RELIEF_MIN_PX = 0.3, 3, 10
HOLLOW_RELIEF_M, RELIEF_MARGIN_M = 0.010, 0.004  # a core this far behind its outline is a container's inside
# (a dustpan's scoop lies 12 mm behind)
FLAT_RELIEF_M = 0.006  # a plate's core lies within this of its outline's plane


@dataclass(frozen=True)
class Cues:
    aspect: float  # bounding box width / height in the image
    elongation: float  # long / short side of the minimum-area rectangle
    rect_fill: float  # area / minimum-area rectangle, at most 1
    ellipse_iou: float  # overlap with the ellipse fitted to the outline
    closed_ellipse_iou: float  # the same with narrow notches closed (a plate seen through a rack's tines)
    corners: int  # vertices of the hull's polygon at 2 % of the perimeter
    end_width: float  # width near the narrower end / widest width, along the long axis
    edge_density: float  # edges inside the region per sqrt(area)
    light_plate: float  # fraction of neutral pixels, lit or shaded (a coloured scale's weighing plate)
    shade_ratio: float  # value's 10th percentile over its 90th: the darkest faces against the brightest
    core_shade: float  # share of the region's core in shade (CORE_SHARE, SHADE_OF_TOP): inner walls, tall sides
    body_ellipse_iou: float  # ellipse_iou of the region opened by a disc a quarter of its width (thin parts cut)
    body_share: float  # the opened region's area / the region's
    area_frac: float  # the region's share of the image
    wide_elongation: float  # elongation of the region's wide part (its slices at least 0.6 of the widest)
    level_share: float | None  # share of its inside shaded level (plane faces); None: unreadable (dark, clipped)
    ramp_share: float | None  # share on a shading ramp (a curved surface); None with level_share
    relief_m: float | None = None  # median depth of the core behind the outline's surface; None: no depth known


def cues(mask: np.ndarray, rgb: np.ndarray, depth_m: np.ndarray | None = None) -> Cues:
    m = mask.astype(np.uint8)
    v, u = np.nonzero(mask)
    area = float(mask.sum())
    extent = min(np.ptp(u), np.ptp(v)) + 1  # the smaller extent, in pixels
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outline = max(contours, key=cv2.contourArea)
    _, (rw, rh), _ = cv2.minAreaRect(outline)
    perimeter = cv2.arcLength(outline, True)
    ellipse_iou = _ellipse_iou(m)
    k = max(3, int(NOTCH_SHARE * min(np.ptp(u) + 1, np.ptp(v) + 1)) | 1)
    closed = cv2.morphologyEx(m, cv2.MORPH_CLOSE, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    hull = cv2.approxPolyDP(cv2.convexHull(outline), 0.02 * perimeter, True)
    inner = cv2.erode(m, np.ones((5, 5), np.uint8)).astype(bool)
    edges = cv2.Canny(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), 30, 90).astype(bool)
    _, sat, val = hsv(rgb)
    return Cues(
        aspect=float((np.ptp(u) + 1) / (np.ptp(v) + 1)),
        elongation=float(max(rw, rh) / max(min(rw, rh), 1.0)),
        # the outline runs through its edge pixels' centres, so a small region's count exceeds its rectangle's area
        rect_fill=min(1.0, float(area / max(rw * rh, 1.0))),
        ellipse_iou=ellipse_iou,
        closed_ellipse_iou=_ellipse_iou(closed),
        corners=len(hull),
        end_width=_end_width(u, v),
        edge_density=float((edges & inner).sum() / max(np.sqrt(area), 1.0)),
        light_plate=float(((sat[mask] < PLATE_MAX_SATURATION) & (val[mask] > PLATE_MIN_VALUE)).mean()),
        shade_ratio=float(np.percentile(val[mask], 10) / max(np.percentile(val[mask], 90), 1e-6)),
        core_shade=_core_shade(mask, val, extent),
        **_body(m, np.ptp(u) + 1, np.ptp(v) + 1, area),
        area_frac=area / mask.size,
        wide_elongation=_wide_elongation(u, v),
        **_shading(mask, rgb),
        relief_m=None if depth_m is None else _relief(mask, depth_m, extent),
    )


def _relief(mask: np.ndarray, depth_m: np.ndarray, extent: int) -> float | None:
    """Median depth (m) of the region's core behind the plane through its outline band (negative: before it);
    None when too few pixels of either have depth."""
    m = mask.astype(np.uint8)
    known = np.isfinite(depth_m) & (depth_m > 0)
    inner = cv2.erode(m, np.ones((3, 3), np.uint8)).astype(bool)
    band_px = 2 * RELIEF_BAND_PX + 1
    band = inner & ~cv2.erode(m, np.ones((band_px, band_px), np.uint8)).astype(bool) & known
    k = max(3, int(RELIEF_CORE_SHARE * extent) | 1)
    core = cv2.erode(m, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))).astype(bool) & known
    if band.sum() < RELIEF_MIN_PX or core.sum() < RELIEF_MIN_PX // 2:
        return None
    bv, bu = np.nonzero(band)
    plane, *_ = np.linalg.lstsq(np.c_[bu, bv, np.ones(len(bu))], 1.0 / depth_m[bv, bu], rcond=None)
    cv_, cu = np.nonzero(core)
    surface = np.c_[cu, cv_, np.ones(len(cu))] @ plane
    if np.any(surface <= 0):
        return None
    return float(np.median(depth_m[cv_, cu] - 1.0 / surface))


def _shading(mask: np.ndarray, rgb: np.ndarray) -> dict[str, float | None]:
    """Shares of the region's readable inside (5x5 windows within it, not clipped) shaded level, and on a ramp;
    None when too little of it is readable (a pale can lying in the light, its side clipped but for a sliver), or
    when a clipped region's remainder shows no curve (PARTLY_UNCLIPPED)."""
    value = np.ascontiguousarray(rgb.max(axis=2))
    k3, k5 = np.ones((3, 3), np.uint8), np.ones((5, 5), np.uint8)
    within = cv2.erode(mask.astype(np.uint8), k5).astype(bool)
    inside = within & (value < CLIPPED)
    unknown = {"level_share": None, "ramp_share": None}
    if inside.sum() < max(MIN_SHADED_PX, PARTLY_UNCLIPPED * within.sum()) or np.median(value[mask]) < DARK_VALUE:
        return unknown
    step3 = (cv2.dilate(value, k3).astype(np.float32) - cv2.erode(value, k3))[inside]
    step5 = (cv2.dilate(value, k5).astype(np.float32) - cv2.erode(value, k5))[inside]
    level = step3 <= np.maximum(LEVEL_MIN_LEVELS, LEVEL_STEP * value[inside])
    ramp = ~level & (step5 >= RAMP_RATIO * step3)
    partly = inside.sum() < MIN_UNCLIPPED * within.sum()
    if partly and (ramp.mean() < CURVED_RAMP or inside.sum() < 2 * MIN_SHADED_PX):
        return unknown
    return {"level_share": float(level.mean()), "ramp_share": float(ramp.mean())}


def _core_shade(mask: np.ndarray, val: np.ndarray, extent: int) -> float:
    """Share of the region's core (eroded by CORE_SHARE of its smaller extent) in shade: below SHADE_OF_TOP of the
    region's 90th-percentile value, in patches of at least 3x3 pixels (a plate's rim line is no shade)."""
    k = max(3, int(CORE_SHARE * extent) | 1)
    core = cv2.erode(mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k))).astype(bool)
    shade = ((val < SHADE_OF_TOP * np.percentile(val[mask], 90)) & mask).astype(np.uint8)
    shade = cv2.morphologyEx(shade, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)).astype(bool)
    return float((shade & core).sum() / max(core.sum(), 1))


def _ellipse_iou(m: np.ndarray) -> float:
    """Overlap of a region (uint8) with the ellipse fitted to its outline."""
    contours, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outline = max(contours, key=cv2.contourArea) if contours else None
    if outline is None or len(outline) < 5:
        return 0.0
    fitted = np.zeros_like(m)
    cv2.ellipse(fitted, cv2.fitEllipse(outline), 1, -1)
    inside, fit = m.astype(bool), fitted.astype(bool)
    return float((inside & fit).sum() / max((inside | fit).sum(), 1))


def _body(m: np.ndarray, width: int, height: int, area: float) -> dict[str, float]:
    """The region with its thin parts cut off (an opening by a disc a quarter of its smaller extent): how well an
    ellipse fits what is left, and how much is left."""
    k = max(3, int(0.25 * min(width, height)) | 1)
    body = cv2.morphologyEx(m, cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    contours, _ = cv2.findContours(body, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outline = max(contours, key=cv2.contourArea) if contours else None
    if outline is None or len(outline) < 5:
        return {"body_ellipse_iou": 0.0, "body_share": 0.0}
    fitted = np.zeros_like(body)
    cv2.ellipse(fitted, cv2.fitEllipse(outline), 1, -1)
    inside, fit = body.astype(bool), fitted.astype(bool)
    return {
        "body_ellipse_iou": float((inside & fit).sum() / max((inside | fit).sum(), 1)),
        "body_share": float(inside.sum() / max(area, 1.0)),
    }


def _end_width(u: np.ndarray, v: np.ndarray) -> float:
    """Width across the long axis at the narrower end (the outer fifths) over the widest tenth."""
    pts = np.stack([u, v], axis=1).astype(np.float64)
    pts -= pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts, full_matrices=False)
    s, t = pts @ vt[0], pts @ vt[1]
    edges = np.linspace(*np.percentile(s, [2, 98]), 11)
    widths = np.array(
        [np.ptp(t[(s >= a) & (s < b)]) if ((s >= a) & (s < b)).sum() > 3 else 0.0 for a, b in itertools.pairwise(edges)]
    )
    if widths.max() <= 0:
        return 1.0
    return float(min(widths[:2].mean(), widths[-2:].mean()) / widths.max())


def _wide_elongation(u: np.ndarray, v: np.ndarray) -> float:
    """Elongation (long over short spread) of the region's wide part: the slices across its long axis at least
    0.6 of the widest. A brush's head is a bar across its handle; a pan's body is a disc, whatever its handle."""
    pts = np.stack([u, v], axis=1).astype(np.float64)
    pts -= pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts, full_matrices=False)
    s, t = pts @ vt[0], pts @ vt[1]
    edges = np.linspace(*np.percentile(s, [2, 98]), 11)
    index = np.clip(np.digitize(s, edges) - 1, 0, 9)
    widths = np.array([np.ptp(t[index == k]) if (index == k).sum() > 3 else 0.0 for k in range(10)])
    wide = pts[widths[index] >= 0.6 * widths.max()]
    if len(wide) < 5:
        return 1.0
    low, high = np.linalg.eigvalsh(np.cov((wide - wide.mean(axis=0)).T))
    return float(np.sqrt(high / max(low, 1e-9)))


def _within(x: float, lo: float, hi: float, margin: float) -> float:
    """1 inside [lo, hi], falling linearly to 0 at `margin` outside."""
    return float(np.clip(1.0 - max(lo - x, x - hi, 0.0) / margin, 0.0, 1.0))


def _shaded(share: float | None, lo: float, hi: float, margin: float) -> float:
    """_within for a shading share; 1 when the region's shading is unreadable (the cue then decides nothing)."""
    return 1.0 if share is None else _within(share, lo, hi, margin)


def _plate_on_top(c: Cues, colour: str) -> float:
    """How much a region looks like a scale's light plate on its base: a coloured (or black) region holding a
    neutral plate, or a white-named neutral region of two shades (a light plate on a darker gray base). A gray-named
    region is dark all over (no light plate); a white scale, plate and base clipped alike, is told by its plate's
    rim instead (scores)."""
    if colour == "gray":
        return 0.0
    if colour == "white":
        return _within(c.shade_ratio, 0.0, TWO_TONE_MAX_RATIO, 0.06)
    return _within(c.light_plate, 0.15, 1.0, 0.1)


def two_shades(c: Cues) -> bool:
    """Whether a white-named region is of two shades: a scale's light plate on a darker gray base (named by its
    base), not a white scale whose plate and base both clip white."""
    return _plate_on_top(c, "white") > 0.0


def scores(c: Cues, colour: str) -> dict[str, float]:
    """Score of each kind for a region with these cues and colour name."""
    inf = np.inf
    # without depth, edges inside stand for a rim and inner walls (a decal's or a texture's edges mislead them) ...
    smooth = _within(c.edge_density, 0.0, 1.8, 0.8)  # no rim or inner walls inside
    hollow = _within(c.edge_density, 3.0, inf, 0.8)  # a rim and inner walls inside
    plain_block = _within(c.edge_density, 0.0, 2.2, 0.8)
    round_smooth = smooth
    flat = _within(c.edge_density, 0.0, 2.6, 0.6)
    solid = 1.0  # no inside behind the outline (unknown without depth)
    if c.relief_m is not None:  # ... with depth, the relief says it: only a container's inside lies behind its rim
        hollow = _within(c.relief_m, HOLLOW_RELIEF_M, inf, RELIEF_MARGIN_M)
        solid = 1.0 - hollow
        # (a cup's handle and rim are edges still: a can's smoothness keeps them; a ball has neither)
        smooth, plain_block, round_smooth = smooth * solid, solid, solid
        flat = _within(c.relief_m, -FLAT_RELIEF_M, FLAT_RELIEF_M, RELIEF_MARGIN_M)
    round_outline = _within(c.corners, 7.5, inf, 1.0)
    plate_on_top = _plate_on_top(c, colour)
    # a white scale: a plate's rim inside, around a core that stays lit
    plate_set_in = (
        float(colour == "white")
        * _within(c.edge_density, 2.7, inf, 0.2)
        * _within(c.core_shade, 0.0, 0.17, 0.05)
        * _within(c.corners, 0.0, 6.0, 1.0)
    )
    body = _within(c.end_width, 0.8, 1.0, 0.1)  # as wide at its ends as in its middle
    necked = _within(c.end_width, 0.0, 0.66, 0.1) * _within(c.end_width, 0.32, 1.0, 0.1)
    round_body = _within(c.body_ellipse_iou, 0.94, 1.0, 0.02)  # an ellipse once thin parts are cut off
    # shading: a ball has no level face, a block is level faces with steps between them (little ramp), a standing
    # can a level top above a side shaded across
    no_level_face = _shaded(c.level_share, 0.0, 0.1, 0.1)
    # a plate's top is level nearly all over (252 seen: at least 0.76 where readable), a ball's nowhere (0 of 515): a
    # small ball seen a little wider than tall is no plate
    level_top = _shaded(c.level_share, 0.5, 1.0, 0.2)
    curved = _shaded(c.ramp_share, 0.35, 1.0, 0.1)
    shaded_round = 0.0 if c.ramp_share is None else _within(c.ramp_share, 0.6, 1.0, 0.1)  # ramps nearly all over
    standing_can = (
        _within(c.aspect, 0.45, 0.9, 0.1)
        * (0.0 if c.ramp_share is None else curved)
        * _shaded(c.level_share, 0.1, 1.0, 0.08)
        * _within(c.end_width, 0.66, 1.0, 0.1)
    )
    out = {
        # a ball: round and smooth; an edited goal re-projects its seen half, which stretches it upward a little
        "sphere": _within(c.elongation, 1.0, 1.2, 0.08)
        * _within(c.aspect, 0.75, 1.1, 0.03)
        * _within(c.ellipse_iou, 0.94, 1.0, 0.04)
        * no_level_face
        * round_smooth,
        "bowl": _within(c.elongation, 1.0, 1.2, 0.1)
        * _within(c.ellipse_iou, 0.92, 1.0, 0.04)
        * _within(c.aspect, 0.85, 1.2, 0.1)
        * hollow,
        # (seen through a rack's tines, the tines' notches closed)
        "plate": _within(c.aspect, 1.08, 1.5, 0.08)
        * _within(max(c.ellipse_iou, c.closed_ellipse_iou), 0.96, 1.0, 0.03)
        * flat
        * level_top,
        # a pan: a narrow handle at one end, or a round body with a thin part cut off (a handle seen end-on)
        "pan": max(
            _within(c.end_width, 0.0, 0.3, 0.1) * _within(c.ellipse_iou, 0.0, 0.8, 0.08),
            round_body * _within(c.body_share, 0.0, 0.96, 0.02) * _within(c.ellipse_iou, 0.0, 0.85, 0.04),
        ),
        "platform": max(plate_on_top * _within(c.corners, 0.0, 6.0, 1.0) * (1.0 - 0.5 * round_outline), plate_set_in)
        * _within(c.elongation, 1.0, PLATFORM_MAX_ELONGATION, 0.3),
        "box": _within(c.corners, 0.0, 6.5, 2.5)
        * _within(c.ellipse_iou, 0.0, 0.94, 0.03)
        * plain_block
        * _within(c.rect_fill, 0.8, 1.0, 0.08)
        * _within(c.elongation, 1.0, BOX_MAX_ELONGATION, 0.4)
        * (1.0 - curved if c.ramp_share is not None else 1.0)
        * (1.0 - plate_on_top),
        "lidded_box": hollow
        * (1.0 - shaded_round)  # an open box's walls and floor are level faces
        * (1.0 - plate_set_in)  # and in the shade
        * _within(c.corners, 0.0, 6.5, 1.5)
        * _within(c.ellipse_iou, 0.0, 0.9, 0.04)
        * (1.0 - round_body),
        "cylinder": max(
            _within(c.aspect, 0.45, 0.9, 0.1) * round_outline * body,  # upright: rounded ends
            _within(c.elongation, 1.8, 3.6, 0.3) * _within(c.rect_fill, 0.88, 1.0, 0.05) * body,  # lying
            standing_can,  # upright, too small for its ends to look round
        )
        * _shaded(c.ramp_share, 0.2, 1.0, 0.1)  # a side shaded across, not level faces
        * max(smooth, shaded_round),  # (a dark can's highlight band is edges inside, on a side that ramps)
        "bottle": necked * _within(c.elongation, 1.9, 4.5, 0.3) * solid,
    }
    # the tasks' objects; a speck (a screw) is nothing else, a bar with a handle (a brush) is no pan
    speck = _within(c.area_frac, 0.0, SPECK_AREA_FRAC, 2e-4) * _within(c.elongation, 1.6, inf, 0.3)
    brush = _within(c.end_width, 0.0, 0.3, 0.1) * _within(c.wide_elongation, 1.7, inf, 0.2)
    out = {k: v * (1.0 - speck) for k, v in out.items()}
    # a rack: tines all over it (edges), and gaps between them (it fills little of its rectangle, a box much)
    rack = _within(c.edge_density, 4.0, inf, 0.8) * _within(c.rect_fill, 0.0, 0.62, 0.05)
    out["pan"] *= 1.0 - brush
    out["lidded_box"] *= (1.0 - brush) * (1.0 - rack)
    polygonal = _within(c.corners, 0.0, 6.5, 1.0)
    out |= {
        "screw": speck,
        "brush": brush,
        "cup": round_outline
        * _within(c.edge_density, 2.5, inf, 0.6)
        * _within(c.aspect, 0.45, 0.82, 0.08)
        * _within(c.elongation, 1.3, 3.0, 0.1),
        "dustpan": RESEMBLES
        * hollow
        * (1.0 - shaded_round)
        * (1.0 - plate_set_in)
        * polygonal
        * _within(c.ellipse_iou, 0.0, 0.9, 0.04)
        * (1.0 - brush),
        "dish_rack": rack * polygonal * (1.0 - brush),
        "stand": RESEMBLES
        * polygonal
        * _within(c.rect_fill, 0.3, 0.72, 0.08)
        * _within(c.end_width, 0.4, 1.0, 0.1)
        * _within(c.edge_density, 0.0, 3.5, 0.5),
    }
    return out


UNKNOWN = "unknown"  # a region no kind fits (an inpainting smear, a fragment)
MIN_KIND_SCORE = 0.1


def classify(c: Cues, colour: str) -> tuple[str, dict[str, float]]:
    """The best-scoring kind of a region (UNKNOWN when none scores MIN_KIND_SCORE), and every kind's score."""
    s = scores(c, colour)
    best = max(s, key=s.get)
    return (best if s[best] >= MIN_KIND_SCORE else UNKNOWN), s
