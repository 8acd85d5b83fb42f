"""Colour regions of a table-top image: every pixel named by colour in a shading-invariant way, then grouped into
connected regions (the offline segmenter's instance proposals).

Shading under white light scales a surface's red, green and blue together: its hue and its saturation
(max - min) / max stay, only its value changes. So a colour is named by hue (nearest of the palette's hue
centres) wherever the pixel has chroma to read it from, on lit and shaded faces alike, with no brightness bound.
The table is found, not assumed: it is the image's dominant chromaticity (the densest hue-saturation cell), and
pixels of that chromaticity are background at any brightness (its shadows included). Unsaturated pixels are
achromatic; their regions are named white, gray or black by their brightest faces (a white object's lit top is
near full scale, a gray one's about 0.7, a black one's dark on every face), not pixel by pixel, since shading
alone turns white to gray.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# hue ranges [deg] of the chromatic colour names, [start, end), as the camera renders the palette: a lit face whose
# brightest channel clips turns its hue (orange towards yellow, pink towards magenta), so a range reaches as far
# as its colour's clipped faces do, and its neighbour's shaded faces do not
HUE_RANGES: dict[str, tuple[float, float]] = {
    "red": (345.0, 15.0),
    "orange": (15.0, 48.0),
    "yellow": (48.0, 80.0),
    "green": (80.0, 160.0),
    "cyan": (160.0, 200.0),
    "blue": (200.0, 255.0),
    "purple": (255.0, 296.0),
    "pink": (296.0, 345.0),
}
HUES = {c: ((lo + ((hi - lo) % 360.0) / 2) % 360.0) for c, (lo, hi) in HUE_RANGES.items()}  # range middles
CHROMATIC = tuple(HUES)
ACHROMATIC = ("white", "gray", "black")
MIN_SATURATION = 0.14  # below: achromatic (the palette's palest shade keeps ~0.2 on its lit faces)
MIN_VALUE = 0.12  # below: too dark to read a hue from (black, deep shadow)
TABLE_HUE_TOL_DEG = 6.0
TABLE_SAT_TOL = 0.08
WHITE_MIN_BRIGHT = 0.76  # 90th percentile of value: white above (a white can's sides: 0.79), gray below (0.73)
WHITE_MIN_SHADED = 0.22  # 5th percentile of value: a white object's shaded faces stay above
BLACK_MAX_MEDIAN = 0.2  # median value of a black region (its lit faces stay dark)
BLACK_MIN_FRACTION = 0.05  # ... or this fraction of dark pixels (a black scale under its light weighing plate;
# a white or gray object's darkest faces stay above 0.2)
# two touching objects of one hue, a pale shade and a deep one (light blue, dark blue), are one region by hue: they
# are split by saturation, which shading leaves alone, when its two modes are this far apart
SPLIT_SATURATION_RATIO = 0.65
PART_BORDER_FRACTION = 0.6  # an unsaturated region this much bordered by one region can be its lit face ...
PLAIN_TINT = 0.035  # ... when its median saturation shows a hue this plainly, the hue of that region ...
PALE_TINT, PALE_BORDER_FRACTION = 0.07, 0.3  # ... or this much when tinted this strongly (half the colour bound): the
# lit part of a pale plate whose shaded part (a shadow across it, its rim) reads as the colour; a white object
# under white light keeps its saturation near 0
SPLIT_BLACK_MAX, SPLIT_LIGHT_MIN = 0.15, 0.55  # a black object's value (lit faces too) and a light one's
SPLIT_MIN_PX = 30
STRIP_THICKNESS = 0.7  # a scale's base sides: at most this thick (px per column) as its plate (0.2-0.57 seen)
LIT_FACE_MIN_VALUE = 0.6  # an unsaturated region darker than this is no lit face of a coloured object
# a pale surface whose saturation sits at MIN_SATURATION splits along a ragged line into a colour and white: the two
# are one surface where the pixels on either side of the line differ by no more than this (no edge between them)
SAME_SURFACE_HUE_DEG, SAME_SURFACE_SAT, SAME_SURFACE_VAL = 15.0, 0.04, 0.06
SAME_SURFACE_MIN_SAT = 0.5 * MIN_SATURATION  # the white side is tinted with the colour, just under the bound
SAME_SURFACE_MIN_BORDER = 0.1  # share of the white part's outline along the line (and at least 10 px)
ACHROMATIC_LABEL = len(CHROMATIC)
BACKGROUND_LABEL = -1


@dataclass(frozen=True)
class Region:
    """One connected region of one colour label: its mask and colour name (white/gray/black for achromatic)."""

    mask: np.ndarray
    colour: str

    @property
    def area(self) -> int:
        return int(self.mask.sum())


def hsv(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hue [deg], saturation and value in [0, 1], float32."""
    x = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL).astype(np.float32)
    return x[..., 0] * (360.0 / 256.0), x[..., 1] / 255.0, x[..., 2] / 255.0


def hue_distance(h: np.ndarray, centre: float) -> np.ndarray:
    return np.abs((h - centre + 180.0) % 360.0 - 180.0)


def table_chromaticity(hue: np.ndarray, sat: np.ndarray, val: np.ndarray) -> tuple[float, float] | None:
    """(hue, saturation) of the densest chromatic cell when it covers a fifth of the image, else None."""
    sel = (sat >= MIN_SATURATION) & (val >= MIN_VALUE)
    if sel.sum() < 0.2 * sel.size:
        return None
    hist, he, se = np.histogram2d(hue[sel], sat[sel], bins=(72, 25), range=((0, 360), (0, 1)))
    i, j = np.unravel_index(np.argmax(hist), hist.shape)
    if hist[i, j] < 0.1 * sel.size:
        return None
    near = sel & (hue_distance(hue, (he[i] + he[i + 1]) / 2) <= 5.0) & (np.abs(sat - (se[j] + se[j + 1]) / 2) <= 0.04)
    return float(np.median(hue[near])), float(np.median(sat[near]))


def label_pixels(rgb: np.ndarray) -> np.ndarray:
    """Per pixel: index into CHROMATIC, ACHROMATIC_LABEL, or BACKGROUND_LABEL (the table's chromaticity)."""
    hue, sat, val = hsv(rgb)
    chromatic = (sat >= MIN_SATURATION) & (val >= MIN_VALUE)
    family = np.full(hue.shape, ACHROMATIC_LABEL, np.int8)
    for k, (lo, hi) in enumerate(HUE_RANGES.values()):
        family[(hue >= lo) & (hue < hi) if lo < hi else (hue >= lo) | (hue < hi)] = k
    labels = np.where(chromatic, family, np.int8(ACHROMATIC_LABEL)).astype(np.int8)
    table = table_chromaticity(hue, sat, val)
    if table is not None:
        th, ts = table
        on_table = chromatic & (hue_distance(hue, th) <= TABLE_HUE_TOL_DEG) & (np.abs(sat - ts) <= TABLE_SAT_TOL)
        labels[on_table] = BACKGROUND_LABEL
    return labels


def achromatic_name(val: np.ndarray) -> str:
    """white, gray or black for the values of one unsaturated region: black when dark all over or in a part
    (a black scale's base under its light plate), white when its brightest faces are near full scale and its
    darkest are not gray (a gray scale's base under the same plate)."""
    if np.median(val) <= BLACK_MAX_MEDIAN or (val < 0.15).mean() >= BLACK_MIN_FRACTION:
        return "black"
    white = np.percentile(val, 90) >= WHITE_MIN_BRIGHT and np.percentile(val, 5) >= WHITE_MIN_SHADED
    return "white" if white else "gray"


def fill_holes(mask: np.ndarray) -> np.ndarray:
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    filled = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(filled, contours, -1, 1, thickness=cv2.FILLED)
    return filled.astype(bool) | mask


def _saturation_split(comp: np.ndarray, sat: np.ndarray, val: np.ndarray) -> list[np.ndarray]:
    """A region of one hue as one or two regions: split where its saturation has two modes far apart. The
    decision rests on the region's inside (its outline blends with the table) lit below full scale (clipping
    washes a pale colour out further); every pixel then goes by its own saturation."""
    inside = cv2.erode(comp.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    reliable = inside & (val < 0.96)
    if reliable.sum() < 40:
        return [comp]
    values = np.clip(sat[reliable] * 255.0, 0, 255).astype(np.uint8)
    threshold, _ = cv2.threshold(values.reshape(-1, 1), 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    low = sat * 255.0 <= threshold
    if min((reliable & low).sum(), (reliable & ~low).sum()) < max(30, 0.1 * reliable.sum()):
        return [comp]
    if np.median(sat[reliable & low]) >= SPLIT_SATURATION_RATIO * np.median(sat[reliable & ~low]):
        return [comp]
    return [comp & low, comp & ~low]


def _brightness_split(comp: np.ndarray, val: np.ndarray) -> list[np.ndarray]:
    """An unsaturated region as its black part and the rest, when it holds both black and light pixels: a black
    ball on a white scale's plate, which touch. The parts are joined again where one is the other's weighing
    plate (a black scale's base under its light plate, see regions()). A region at the image border (the floor,
    the robot) is no object, but a black object that meets it in the image is (a black pan whose handle touches
    the gripper): its black part is kept apart, whatever else it holds."""
    h, w = comp.shape
    v, u = np.nonzero(comp)
    dark, light = comp & (val <= SPLIT_BLACK_MAX), comp & (val >= SPLIT_LIGHT_MIN)
    if v.min() == 0 or u.min() == 0 or v.max() == h - 1 or u.max() == w - 1:
        return [comp & ~dark, dark]
    if dark.sum() < SPLIT_MIN_PX or light.sum() < SPLIT_MIN_PX:
        return [comp]
    return [dark, comp & ~dark]


def _components(rgb: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Connected components of each colour label, side by side (4-connected: two objects of one colour whose
    corners meet at one pixel stay apart): an id map (0 = none) and each id's colour name ("achromatic" until its
    region is named white, gray or black)."""
    labels = label_pixels(rgb)
    _, sat, val = hsv(rgb)
    kernel = np.ones((3, 3), np.uint8)
    ids = np.zeros(labels.shape, np.int32)
    names = [""]
    for label in range(len(CHROMATIC) + 1):
        mask = cv2.morphologyEx((labels == label).astype(np.uint8), cv2.MORPH_OPEN, kernel)
        n, comp = cv2.connectedComponents(mask, connectivity=4)
        for i in range(1, n):
            if label == ACHROMATIC_LABEL:
                pieces = _brightness_split(comp == i, val)
            else:
                pieces = _saturation_split(comp == i, sat, val)
            for piece in pieces:
                for part in _connected(piece):
                    names.append(CHROMATIC[label] if label < len(CHROMATIC) else "achromatic")
                    ids[part] = len(names) - 1
    return ids, names


def _connected(mask: np.ndarray) -> list[np.ndarray]:
    n, comp = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    return [comp == i for i in range(1, n)]


def _around(mask: np.ndarray) -> np.ndarray:
    """The 2-pixel ring around a mask."""
    return cv2.dilate(mask.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool) & ~mask


def _pieces_of(ids: np.ndarray, names: list[str], ring: np.ndarray, name: str) -> np.ndarray:
    """The components of colour `name` that reach into `ring`, whole."""
    return np.isin(ids, [k for k in np.unique(ids[ring]) if k > 0 and names[k] == name])


def _bordering(ids: np.ndarray, i: int, names: list[str] | None = None) -> tuple[int, float]:
    """The id bordering component i most, and the fraction of i's outline it borders (with `names`: the
    fraction all components of that one's colour border)."""
    ring = _around(ids == i)
    around = ids[ring]
    around = around[around > 0]
    if around.size == 0:
        return 0, 0.0
    values, counts = np.unique(around, return_counts=True)
    k = int(np.argmax(counts))
    if names is None:
        return int(values[k]), float(counts[k] / ring.sum())
    same = sum(c for v, c in zip(values, counts, strict=True) if names[v] == names[values[k]])
    return int(values[k]), float(same / ring.sum())


def _weighing_plate_base(ids: np.ndarray, names: list[str], i: int, val: np.ndarray, sat: np.ndarray) -> int:
    """The base under a scale's weighing plate: component i is neutral and light, and the regions of the colour
    bordering it most are a strip below it spanning most of its width (the base's sides, in pieces where something
    in front hides part of them), thinner than the plate (a scale is far lower than it is deep: a block or the
    table behind a white object is not); else 0."""
    own = ids == i
    if np.median(sat[own]) > 0.03 or np.median(val[own]) < 0.6:
        return 0
    other, border = _bordering(ids, i, names)
    if other == 0 or border < 0.15:
        return 0
    base = _pieces_of(ids, names, _around(own), names[other])
    tv, tu = np.nonzero(own)
    bv, bu = np.nonzero(base)
    spans = np.ptp(bu) >= 0.8 * np.ptp(tu)
    thin = base.sum() / (np.ptp(bu) + 1) <= STRIP_THICKNESS * own.sum() / (np.ptp(tu) + 1)
    return other if spans and thin and bv.mean() > tv.mean() else 0


def _lit_face_of(ids: np.ndarray, names: list[str], i: int, hue: np.ndarray, sat: np.ndarray, val: np.ndarray) -> int:
    """The pale object whose lit face component i is, or 0: mostly bordered by one colour and faintly tinted
    with its hue (a light pink pan's lit floor; a third of its outline is enough when the tint is plain, a light
    pink plate's top beside its shaded part), or washed out to full scale all over and no larger than the
    coloured faces around it (a pink box's top in the light; a white object has shaded faces in its own region,
    a white plate under a red block is far larger than the block). A face plainly tinted with another hue is
    the face of a region of that hue beside it, if any (a light pink bottle's cap in the light against a cyan
    pan)."""
    other, border = _bordering(ids, i, names)
    if other == 0 or names[other] not in HUES:
        return 0
    own = ids == i
    lit = np.median(val[own]) >= LIT_FACE_MIN_VALUE  # a face in the light is bright: a gray block in a bowl is not
    saturation, face_hue = np.median(sat[own]), np.median(hue[own])
    own_hue = hue_distance(face_hue, HUES[names[other]]) <= 30.0
    tint = saturation if lit and own_hue else 0.0
    if (tint >= PLAIN_TINT and border >= PART_BORDER_FRACTION) or (
        tint >= PALE_TINT and border >= PALE_BORDER_FRACTION
    ):
        return other
    ring = _around(own)
    if saturation >= PLAIN_TINT and not own_hue:
        tinted = min(HUES, key=lambda c: hue_distance(face_hue, HUES[c]))
        ks, counts = np.unique(ids[ring], return_counts=True)
        theirs = [(c, int(k)) for k, c in zip(ks, counts, strict=True) if k > 0 and names[k] == tinted]
        return max(theirs)[1] if lit and theirs else 0
    faces = _pieces_of(ids, names, ring, names[other])
    washed_out = np.percentile(val[own], 10) >= 0.93 and own.sum() <= 1.5 * faces.sum()
    return other if washed_out and border >= 0.15 else 0


def _same_surface_as(
    ids: np.ndarray, names: list[str], i: int, hue: np.ndarray, sat: np.ndarray, val: np.ndarray
) -> int:
    """The coloured component that unsaturated component i is one surface with, or 0: a pale surface (a light pink
    plate's top) whose saturation straddles MIN_SATURATION is cut by it along a ragged line with no edge in the
    image: the pixels on either side have one hue, saturation and brightness. Two objects that touch differ across
    the line where they meet (a white box by a pale pink one: their saturations are apart)."""
    kernel = np.ones((3, 3), np.uint8)
    own = ids == i
    grown = cv2.dilate(own.astype(np.uint8), kernel).astype(bool)
    outline = int((grown & ~own).sum())
    for j in np.unique(ids[grown & ~own]):
        if j <= 0 or names[j] not in HUES:
            continue
        theirs = grown & (ids == j)  # their side of the line
        mine = own & cv2.dilate((ids == j).astype(np.uint8), kernel).astype(bool)  # my side
        if theirs.sum() < max(10, SAME_SURFACE_MIN_BORDER * outline) or mine.sum() < 10:
            continue
        same = (
            hue_distance(np.median(hue[mine]), float(np.median(hue[theirs]))) <= SAME_SURFACE_HUE_DEG
            and abs(np.median(sat[mine]) - np.median(sat[theirs])) <= SAME_SURFACE_SAT
            and abs(np.median(val[mine]) - np.median(val[theirs])) <= SAME_SURFACE_VAL
            and np.median(sat[mine]) >= SAME_SURFACE_MIN_SAT
        )
        if same:
            return int(j)
    return 0


def regions(rgb: np.ndarray, min_area: int) -> list[Region]:
    """Connected regions of each colour, unsaturated parts joined to their object (a pale object's lit face, a
    scale's weighing plate, the rest of a pale surface cut by the saturation bound), holes filled (a
    highlight, a pan's floor and what lies on it), specks below `min_area` and regions touching the image border
    (floor, robot, table edge) left out."""
    ids, names = _components(rgb)
    hue, sat, val = hsv(rgb)
    sizes = np.bincount(ids.ravel(), minlength=len(names))
    for i in np.flatnonzero(sizes >= min_area // 4):
        if i > 0 and names[i] == "achromatic":
            j = (
                _lit_face_of(ids, names, int(i), hue, sat, val)
                or _weighing_plate_base(ids, names, int(i), val, sat)
                or _same_surface_as(ids, names, int(i), hue, sat, val)
            )
            if j:  # the face joins its object, and so do the other faces of that colour around it
                ids[_pieces_of(ids, names, _around(ids == i), names[j])] = j
                ids[ids == i] = j
    h, w = ids.shape
    out: list[Region] = []
    for i in np.unique(ids):
        m = ids == i
        if i == 0 or m.sum() < min_area:
            continue
        v, u = np.nonzero(m)
        if v.min() == 0 or u.min() == 0 or v.max() == h - 1 or u.max() == w - 1:
            continue
        colour = names[i] if names[i] != "achromatic" else achromatic_name(val[m])
        out.append(Region(fill_holes(m), colour))
    return out
