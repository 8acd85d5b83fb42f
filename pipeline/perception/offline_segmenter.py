"""Offline segmenter for the simulator's objects: colour thresholds in HSV plus coarse shape cues.

Works on the RGB image alone (never on simulator ground truth). A phrase names an object by colour and/or shape
words ("the red block", "the plate"). Colour picks pixels; connected components are instances; shape words rank
and filter them by silhouette cues (elongation, fill, aspect). Dark and gray objects (a pan, a black scale with a
white weighing plate) are not one colour under the lights: their faces range from black to white, but all are
unsaturated, unlike the wooden table. So for gray and black the instance is the unsaturated component that holds
enough pixels of that colour, with its holes filled (a pan's rim encloses its floor and whatever lies on it).
A part word ("the lid of the blue box") names a differently coloured part attached to the named object: the
largest chromatic component, not of the object's own pixels, that touches the object's silhouette.
Limits, by design of a no-model backend: brown is not separable from the wooden table, components touching the
image border are ignored (the floor, the robot base), and white/gray/black objects compete with the white and
gray robot links (shape words disambiguate).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.perception.segmenter import Detection, SegmentationError, Segmenter, box_of, check_rgb

# hue centre [deg], min saturation, min value
CHROMATIC: dict[str, tuple[float, float, float]] = {
    "red": (0.0, 0.55, 0.15),
    "orange": (26.0, 0.75, 0.45),
    "yellow": (50.0, 0.6, 0.35),
    "green": (128.0, 0.45, 0.12),
    "cyan": (184.0, 0.55, 0.2),
    "blue": (222.0, 0.5, 0.12),
    "purple": (282.0, 0.45, 0.12),
    "pink": (335.0, 0.3, 0.45),
}
HUE_TOLERANCE_DEG = 14.0
# max saturation, value range
ACHROMATIC: dict[str, tuple[float, float, float]] = {
    "white": (0.12, 0.80, 1.01),
    "gray": (0.12, 0.25, 0.78),
    "black": (1.0, 0.0, 0.10),
}
# gray/black instances: unsaturated components (max saturation) holding at least this fraction of the colour
UNSATURATED_MAX_S = 0.15
DARK_MIN_FRACTION = 0.1
COLOUR_WORDS: dict[str, str] = {c: c for c in (*CHROMATIC, *ACHROMATIC)} | {"grey": "gray", "violet": "purple"}
SHAPE_WORDS: dict[str, str] = {
    "block": "box",
    "cube": "box",
    "brick": "box",
    "box": "box",
    "cylinder": "cylinder",
    "can": "cylinder",
    "ball": "sphere",
    "sphere": "sphere",
    "plate": "plate",
    "dish": "plate",
    "disc": "plate",
    "bottle": "bottle",
    "pan": "pan",
    "bowl": "bowl",
    "scale": "platform",
    "platform": "platform",
    "chest": "lidded_box",
}
PART_WORDS = ("lid",)
FILLER_WORDS = {"the", "a", "an", "small", "big", "large", "little", "object", "lidded", "of", "s"}
ATTACHED_PX = 4  # a part's component lies within this many pixels of its object's silhouette


@dataclass(frozen=True)
class ObjectPhrase:
    colour: str | None
    shape: str | None  # a shape class (value of SHAPE_WORDS)
    part: str | None = None  # a part of the object (PART_WORDS), e.g. its lid


def parse_phrase(phrase: str) -> ObjectPhrase:
    """Colour, shape and part words of an object phrase; other words are errors so typos do not go unnoticed."""
    colour = shape = part = None
    words = re.findall(r"[a-z]+", phrase.lower())
    for w in words:
        if w in COLOUR_WORDS and colour is None:
            colour = COLOUR_WORDS[w]
        elif w in SHAPE_WORDS and shape is None:
            shape = SHAPE_WORDS[w]
        elif w in PART_WORDS and part is None:
            part = w
        elif w not in FILLER_WORDS:
            raise SegmentationError(
                f"offline segmenter: unknown word {w!r} in {phrase!r}; colours: {', '.join(sorted(COLOUR_WORDS))}; "
                f"shapes: {', '.join(sorted(SHAPE_WORDS))}; parts: {', '.join(PART_WORDS)}"
            )
    if colour is None and shape is None:
        raise SegmentationError(f"offline segmenter: {phrase!r} names no colour or shape word for the object")
    return ObjectPhrase(colour, shape, part)


def colour_mask(rgb: np.ndarray, colour: str) -> np.ndarray:
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL).astype(np.float32)
    hue, sat, val = hsv[..., 0] * (360.0 / 256.0), hsv[..., 1] / 255.0, hsv[..., 2] / 255.0
    if colour in CHROMATIC:
        centre, min_s, min_v = CHROMATIC[colour]
        d = np.abs((hue - centre + 180.0) % 360.0 - 180.0)
        return (d <= HUE_TOLERANCE_DEG) & (sat >= min_s) & (val >= min_v)
    max_s, v0, v1 = ACHROMATIC[colour]
    return (sat <= max_s) & (val >= v0) & (val < v1)


def fill_holes(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return filled.astype(bool) | mask


def unsaturated_mask(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL)[..., 1] <= UNSATURATED_MAX_S * 255.0


def _round_body(mask: np.ndarray) -> float:
    """A pan seen from any side: opening with a disc a quarter of its size removes the handle; what remains must
    fill its bounding box like an ellipse (pi/4) and keep most, but not all, of the area (a ball or a block has no
    handle to lose; a pan whose handle is hidden is missed, by design)."""
    k = max(3, int(0.25 * np.sqrt(mask.sum())))
    body = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (k, k)))
    if not body.any():
        return 0.0
    _, _, bw, bh = cv2.boundingRect(body)
    fill = body.sum() / float(bw * bh)
    kept = body.sum() / float(mask.sum())
    elliptic = np.clip(1.0 - abs(fill - np.pi / 4) / 0.12, 0.0, 1.0)
    return float(elliptic * np.clip(min(kept - 0.5, 0.95 - kept) / 0.03, 0.0, 1.0))


def _shape_score(mask: np.ndarray, shape: str | None) -> float:
    """How well a silhouette fits a shape class, in [0, 1]; coarse on purpose (views are oblique)."""
    if shape is None:
        return 1.0
    v, u = np.nonzero(mask)
    w, h = int(np.ptp(u)) + 1, int(np.ptp(v)) + 1
    cov = np.cov(np.stack([u, v]).astype(np.float64)) + 1e-6 * np.eye(2)
    ev = np.sort(np.linalg.eigvalsh(cov))
    elong = float(np.sqrt(ev[1] / ev[0]))
    fill = mask.sum() / float(w * h)
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    hull = cv2.contourArea(cv2.convexHull(max(contours, key=cv2.contourArea)))
    solidity = mask.sum() / max(hull, 1.0)
    aspect = w / h

    def near(x: float, lo: float, hi: float, soft: float = 0.25) -> float:
        return float(np.clip(1.0 - max(lo - x, x - hi, 0.0) / soft, 0.0, 1.0))

    score = {
        "box": near(elong, 1.0, 2.2) * near(fill, 0.55, 1.0),
        "platform": near(elong, 1.0, 2.5) * near(fill, 0.55, 1.0),
        "lidded_box": near(fill, 0.3, 1.0),
        "cylinder": max(near(1 / aspect, 1.35, 3.5), near(elong, 2.0, 4.0)) * near(fill, 0.55, 1.0),
        "bottle": max(near(1 / aspect, 1.4, 4.0), near(elong, 2.0, 5.0)),
        "sphere": near(elong, 1.0, 1.3) * near(fill, 0.65, 0.9),
        "plate": near(aspect, 1.2, 3.0) * near(solidity, 0.9, 1.0),
        "bowl": near(aspect, 1.1, 3.0) * near(solidity, 0.85, 1.0),
        "pan": _round_body(mask) * near(solidity, 0.6, 0.97),
    }[shape]
    return float(score)


class OfflineSegmenter(Segmenter):
    """Colour components ranked by shape fit; `min_area_frac` drops specks, `min_shape_score` drops misfits.

    With a colour word the shape only ranks (loose bound); a shape word alone must fit well (strict bound).
    """

    name = "offline"

    def __init__(self, min_area_frac: float = 2.5e-4, min_shape_score: float = 0.2, shape_only_score: float = 0.6):
        self.min_area_frac = min_area_frac
        self.min_shape_score = min_shape_score
        self.shape_only_score = shape_only_score

    def segment(self, rgb: np.ndarray, phrase: str) -> list[Detection]:
        check_rgb(rgb, "offline segmenter")
        want = parse_phrase(phrase)
        if want.part is None:
            return self._objects(rgb, want)
        # the object's own silhouette changes shape as its part moves (a box under its closed lid is a strip):
        # with a colour word, the colour alone finds it
        objects = self._objects(rgb, ObjectPhrase(want.colour, None) if want.colour else want)
        parts = [(whole, _attached_part(rgb, whole.mask, self._min_area(rgb))) for whole in objects]
        return [
            Detection(m, whole.score, box_of(m), f"{want.part} of {whole.label}") for whole, m in parts if m is not None
        ]

    def _min_area(self, rgb: np.ndarray) -> int:
        return max(20, int(self.min_area_frac * rgb.shape[0] * rgb.shape[1]))

    def _objects(self, rgb: np.ndarray, want: ObjectPhrase) -> list[Detection]:
        colours = [want.colour] if want.colour else [c for c in (*CHROMATIC, *ACHROMATIC) if c != "orange"]
        h, w = rgb.shape[:2]
        min_area = self._min_area(rgb)
        kernel = np.ones((3, 3), np.uint8)
        bound = self.min_shape_score if want.colour else self.shape_only_score
        found: list[Detection] = []
        for colour in colours:
            dark = colour in ("gray", "black")
            pixels = colour_mask(rgb, colour)
            mask = unsaturated_mask(rgb) if dark else pixels
            mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, kernel)
            n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
            for i in range(1, n):
                x, y, bw, bh, area = stats[i]
                if area < min_area or x == 0 or y == 0 or x + bw >= w or y + bh >= h:
                    continue
                comp = labels == i
                if dark:
                    if pixels[comp].mean() < DARK_MIN_FRACTION:
                        continue
                    comp = fill_holes(comp)
                score = _shape_score(comp, want.shape)
                if score >= bound:
                    found.append(Detection(comp, score, box_of(comp), f"{colour} {want.shape or 'object'}"))
        return sorted(found, key=lambda d: (-d.score, -d.area_px))


def _attached_part(rgb: np.ndarray, whole: np.ndarray, min_area: int) -> np.ndarray | None:
    """The largest chromatic component outside `whole` that touches it (within ATTACHED_PX), or None."""
    near = cv2.dilate(whole.astype(np.uint8), np.ones((2 * ATTACHED_PX + 1,) * 2, np.uint8)).astype(bool)
    best: np.ndarray | None = None
    for colour in CHROMATIC:
        pixels = cv2.morphologyEx(colour_mask(rgb, colour).astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
        _, labels, stats, _ = cv2.connectedComponentsWithStats(pixels, connectivity=8)
        for i in np.flatnonzero(stats[1:, cv2.CC_STAT_AREA] >= min_area) + 1:
            comp = labels == i
            own = (comp & whole).sum() >= 0.5 * comp.sum()
            if not own and (comp & near).any() and (best is None or comp.sum() > best.sum()):
                best = comp & ~whole
    return best
