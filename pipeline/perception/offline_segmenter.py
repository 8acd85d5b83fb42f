"""Offline segmenter for the simulator's objects: colour regions named in a shading-invariant way, each classified
by shape into one of the sim's kinds.

Works on the RGB image alone (never on simulator ground truth). A phrase names an object by colour and/or shape
words ("the red block", "the scale", "the dark blue bottle"). The image is cut into colour regions
(colour_regions.py: a colour is a hue on lit and shaded faces alike; white, gray and black are named per region);
each region is of the kind its silhouette and inner edges fit best (shape_cues.py). A colour word keeps the
regions of that colour; a shape word keeps those classified as one of its kinds ("box" is any box, a lidded one
too; "block" and "cube" only a plain one), and with a colour word, when none of that colour is classified so,
those of that colour that fit the shape best (at least loosely; when none does, every one of that colour but
those surely of another kind, and not of one it looks like with a part unseen: the colour decides and the shape
only ranks). A shade word (dark, light) keeps,
among several of the colour, the darker or paler ones; white stands for gray and gray for white when nothing is
named so (a white lid in the shade, a gray one in the light). A lid of another colour is a part of its box, not an
object of its own. A shape word alone keeps the regions of its kinds (when there is none, those fitting it well,
the best within a margin; a moved object seen from another side can read as a neighbouring kind; when none fits,
those of a kind it looks like with a part unseen: a pan whose handle reads apart is a shallow bowl), so "the
scale" is the scale, not every box-like thing.
A plural shape word ("the yellow screws") names every instance, and with a colour word also the irregular
regions of that colour a few small parts make when they touch (a pile). A part word ("the lid of the blue box")
names the lid of the named object: a region of another colour attached to it from above and resting on it along
its width (open or shut; with a depth image, at the box's depth where they meet: a thing standing behind the box
meets it in the image only, farther off), else, for a lidded box with a lid of its own colour, the topmost face of
the box's region (faces are the pieces between the edges inside it). With no chest seen open, of several regions
with a lid the largest is the chest (shut, it looks like a box, and outsizes a block of a paler shade beside it).
Limits, by design of a no-model backend: brown is not separable from the wooden table, regions touching the
image border are ignored (the floor, the robot base), touching objects of one colour and one saturation are one
region (when it reads as no object of the named kind, a depth image cuts it where one stands in front of the
other: occlusion.py), and a white scale (plate and base clipped alike) is told only by its plate's rim around a
lit core.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.perception.colour_regions import ACHROMATIC, CHROMATIC, Region, hsv, regions
from pipeline.perception.occlusion import occlusion_pieces
from pipeline.perception.segmenter import Detection, SegmentationError, Segmenter, box_of, check_depth, check_rgb
from pipeline.perception.shape_cues import SPECK_AREA_FRAC, classify, cues, two_shades

COLOUR_WORDS: dict[str, str] = {c: c for c in (*CHROMATIC, *ACHROMATIC)} | {"grey": "gray", "violet": "purple"}
# what a shape word names: kinds of the simulator's objects
SHAPE_WORDS: dict[str, frozenset[str]] = {
    "block": frozenset({"box"}),
    "cube": frozenset({"box"}),
    "brick": frozenset({"box"}),
    "box": frozenset({"box", "lidded_box"}),
    "chest": frozenset({"lidded_box"}),
    "cylinder": frozenset({"cylinder"}),
    "can": frozenset({"cylinder"}),
    "ball": frozenset({"sphere"}),
    "sphere": frozenset({"sphere"}),
    "plate": frozenset({"plate"}),
    "dish": frozenset({"plate"}),
    "disc": frozenset({"plate"}),
    "bottle": frozenset({"bottle"}),
    "pan": frozenset({"pan"}),
    "bowl": frozenset({"bowl"}),
    "scale": frozenset({"platform"}),
    "platform": frozenset({"platform"}),
    "cup": frozenset({"cup", "cylinder"}),  # a cup seen from the side is a can to the eye
    "mug": frozenset({"cup", "cylinder"}),
    "screw": frozenset({"screw"}),
    "bolt": frozenset({"screw"}),
    "brush": frozenset({"brush"}),
    "broom": frozenset({"brush"}),
    "dustpan": frozenset({"dustpan"}),
    "rack": frozenset({"dish_rack"}),
    "stand": frozenset({"stand"}),
    "shelf": frozenset({"stand"}),
}
PART_WORDS = ("lid",)
SHADE_WORDS = ("dark", "light")
FILLER_WORDS = {"the", "a", "an", "small", "big", "large", "little", "object", "lidded", "of", "s", "all"}
FILLER_BEFORE_SHAPE = {"dish"}  # "dish rack": a word that is a shape word alone but describes the one after it
LIGHT_NEUTRALS = ("white", "gray")  # a colour word of one stands for the other when nothing is of that one
SHUT_LOOKS_LIKE = frozenset({"box"})  # a lidded box with its lid shut is a box to the eye: when no lidded one is,
CHEST_AREA_RATIO = 0.6  # ... the largest box (and any nearly as large): a chest is several blocks in size
ATTACHED_PX = 4  # a part's region lies within this many pixels of its object's region
ENCLOSED_TOP = 0.8  # a region with its object's just above this share of its top edge lies inside the object
CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
BLEND_SATURATION = 0.8  # a lid's pixel along its box this much less saturated than the lid is a blend of the two
LID_MIN_FRACTION = 0.15  # a lid covers at least this share of its object's region
SHUT_LID_FRACTION = 0.5  # ... and a shut one seen from above, told by its face alone, at least this share
LID_RESTS_ON = 0.8  # ... and rests on it along at least this share of its width (it may overhang a little) ...
# ... or, where depth shows the two meet (_meets: a thing behind the box does not), this share: an open lid leaning
# back, its box turned, shows a side edge rising from the hinge over a quarter of its width (12044, 12104)
LID_RESTS_ON_MEETING = 0.5
MEET_M = 0.03  # ... and, where depth is known, is this near the box in depth where they meet (a lid on its hinge: a
# few mm; a bottle or a bowl behind the box: 15 cm and more)
FLAT_KINDS = ("box", "plate", "platform", "lidded_box")  # what a lid's region can look like
RANK_MARGIN = 0.15  # with no region of the shape's kinds: those fitting it within this of the best
TIE_MARGIN = 0.05  # a region fitting another kind within this of the named one is of either
SHAPE_ONLY_FIT = 0.5  # ... and with no colour word, fitting it at least this well
SHADE_RATIO = 0.8  # a light (dark) region's saturation (value) against the deepest (brightest) of its colour
PILE_AREA_FRAC = 5e-3  # a pile of small parts (screws) is at most this share of the image ...
PILE_FILL, PILE_ELLIPSE = 0.75, 0.7  # ... and fills less of its rectangle, or of its ellipse, than any solid does
FRAGMENT_AREA_FRAC = 2 * SPECK_AREA_FRAC  # a region this small of the colour is a part, partly seen
CONFIDENT_KIND = 0.8  # a region scoring this for some kind is an object of that kind, not a pile
# kinds one is read as where part of it does not show: a pan whose handle is washed out or hidden is a shallow bowl
LOOK_ALIKE: dict[str, frozenset[str]] = {"pan": frozenset({"bowl"}), "bowl": frozenset({"pan"})}
# ... and, only where a colour word has found it, a bottle whose neck reads apart (an edited goal drawn with a seam
# below the neck) is a can: by shape alone a can-like piece (a pan's washed-out handle) would be taken for a bottle
BODY_APART: dict[str, frozenset[str]] = {"bottle": frozenset({"cylinder"})}
SIZE_KINDS = frozenset({"screw"})  # kinds told by size alone (shape_cues: a speck)


@dataclass(frozen=True)
class ObjectPhrase:
    colour: str | None
    shape: str | None  # the shape word (a key of SHAPE_WORDS)
    part: str | None = None  # a part of the object (PART_WORDS), e.g. its lid
    shade: str | None = None  # dark or light (SHADE_WORDS): among several of the colour, the darker or paler
    also: frozenset[str] = frozenset()  # kinds matched besides the shape word's
    plural: bool = False  # the shape word was plural ("the screws"): every instance is meant

    @property
    def kinds(self) -> frozenset[str] | None:
        return None if self.shape is None else SHAPE_WORDS[self.shape] | self.also


def shape_word(word: str) -> tuple[str, bool] | None:
    """(shape word, plural) of a word: "screws" -> ("screw", True), "boxes" -> ("box", True); None if none."""
    if word in SHAPE_WORDS:
        return word, False
    for ending in ("es", "s"):
        stem = word.removesuffix(ending)
        if stem != word and stem in SHAPE_WORDS:
            return stem, True
    return None


def parse_phrase(phrase: str) -> ObjectPhrase:
    """Colour, shape and part words of an object phrase; other words are errors so typos do not go unnoticed."""
    colour = shape = part = shade = None
    plural = False
    words = re.findall(r"[a-z]+", phrase.lower())
    for k, w in enumerate(words):
        nxt = shape_word(words[k + 1]) if k + 1 < len(words) else None
        if w in FILLER_BEFORE_SHAPE and nxt is not None:
            continue
        if w in SHADE_WORDS and shade is None:
            shade = w
        elif w in COLOUR_WORDS and colour is None:
            colour = COLOUR_WORDS[w]
        elif shape_word(w) is not None and shape is None:
            shape, plural = shape_word(w)
        elif w in PART_WORDS and part is None:
            part = w
        elif w not in FILLER_WORDS:
            raise SegmentationError(
                f"offline segmenter: unknown word {w!r} in {phrase!r}; colours: {', '.join(sorted(COLOUR_WORDS))}; "
                f"shapes: {', '.join(sorted(SHAPE_WORDS))}; parts: {', '.join(PART_WORDS)}"
            )
    if colour is None and shape is None:
        raise SegmentationError(f"offline segmenter: {phrase!r} names no colour or shape word for the object")
    return ObjectPhrase(colour, shape, part, shade if colour else None, plural=plural)


@dataclass(frozen=True)
class Instance:
    region: Region
    kind: str  # the best-scoring kind
    scores: dict[str, float]
    hsv: tuple[np.ndarray, np.ndarray, np.ndarray]  # hue, saturation, value of its pixels


class OfflineSegmenter(Segmenter):
    """Colour regions classified by shape; `min_area_frac` drops specks, `min_shape_score` is the loose fit a
    region of the named colour needs when none of that colour is classified as the named shape."""

    name = "offline"

    def __init__(self, min_area_frac: float = 2.5e-4, min_shape_score: float = 0.2):
        self.min_area_frac = min_area_frac
        self.min_shape_score = min_shape_score

    def segment(self, rgb: np.ndarray, phrase: str, depth_m: np.ndarray | None = None) -> list[Detection]:
        check_rgb(rgb, "offline segmenter")
        want = parse_phrase(phrase)
        instances = self.instances(rgb, depth_m)
        # a lidded box's lid is no object of its own, whatever it looks like (an open lid seen edge-on: a bottle)
        lids = {
            id(lid)
            for i in instances
            if i.kind == "lidded_box"
            for lid in [_attached_lid(i, instances, depth_m, any_shape=True)]
            if lid
        }
        candidates = [i for i in instances if id(i) not in lids]
        objects = _matching(candidates, want, self.min_shape_score)
        if depth_m is not None and want.kinds is not None and not any(i.kind in want.kinds for i in objects):
            objects = self._apart(rgb, candidates, want, depth_m) or objects
        if want.plural and want.colour is not None:  # several small parts touching are one region: a pile
            objects += _piles(rgb, [i for i in candidates if all(i is not o for o in objects)], want)
        if not objects and want.part is not None and want.kinds is not None and "lidded_box" in want.kinds:
            shut = ObjectPhrase(want.colour, want.shape, want.part, want.shade, SHUT_LOOKS_LIKE, want.plural)
            boxes = _matching(candidates, shut, self.min_shape_score)
            largest = max((i.region.area for i in boxes), default=0)
            objects = [i for i in boxes if i.region.area >= CHEST_AREA_RATIO * largest]  # a chest outsizes blocks
        if want.part is None:
            return [_detection(i, want, i.region.mask) for i in objects]
        seen_open = any(_reads_open(i) for i in objects)
        if seen_open:  # a lid is a chest's part: a box seen open has one,
            objects = [i for i in objects if _reads_open(i)]  # a plain-looking box only when none is open
        found = [
            (whole, lid)
            for whole in objects
            for lid in [_lid(rgb, whole, instances, want, depth_m, self._min_area(rgb))]
            if lid is not None
        ]
        if not seen_open and len(found) > 1:  # shut chests look like boxes: of several with a lid, the chest
            largest = max(whole.region.area for whole, _ in found)  # outsizes blocks of its colour
            found = [(whole, lid) for whole, lid in found if whole.region.area >= CHEST_AREA_RATIO * largest]
        return [Detection(lid, _score(w, want), box_of(lid), f"{want.part} of {_label(w)}") for w, lid in found]

    def colours_of(self, rgb: np.ndarray, *masks: np.ndarray) -> tuple[str | None, ...]:
        """Per mask, the colour of the region covering most of it; None where no region covers any of it."""
        instances = self.instances(rgb)

        def colour(mask: np.ndarray) -> str | None:
            overlap, name = max(
                ((int((i.region.mask & mask).sum()), i.region.colour) for i in instances), default=(0, None)
            )
            return name if overlap > 0 else None

        return tuple(colour(m) for m in masks)

    def instances(self, rgb: np.ndarray, depth_m: np.ndarray | None = None) -> list[Instance]:
        """Every colour region of the image with its kind (told by its relief too where depth is given)."""
        check_depth(depth_m, rgb, "offline segmenter")
        hsv_image = hsv(rgb)
        return [_instance(rgb, hsv_image, region, depth_m) for region in regions(rgb, self._min_area(rgb))]

    def _min_area(self, rgb: np.ndarray) -> int:
        return max(20, int(self.min_area_frac * rgb.shape[0] * rgb.shape[1]))

    def _apart(
        self, rgb: np.ndarray, candidates: list[Instance], want: ObjectPhrase, depth_m: np.ndarray
    ) -> list[Instance]:
        """When no region of the phrase's colour reads as its kind, the named object may share its region with a
        neighbour of its colour in front of or behind it (a small blue box behind a blue pan's rim): the regions
        cut where the depth steps (occlusion.py), and the pieces of the named kind, if any. Only then: a bowl's
        or a pan's floor lies behind its near rim too and would be cut off."""
        hsv_image, min_area = hsv(rgb), self._min_area(rgb)
        pieces = [
            _instance(rgb, hsv_image, Region(piece, i.region.colour), depth_m)
            for i in candidates
            if want.colour is None or i.region.colour == want.colour
            for piece in occlusion_pieces(i.region.mask, depth_m, min_area)
            if piece.sum() < i.region.area
        ]
        found = _matching(pieces, want, self.min_shape_score)
        return [i for i in found if i.kind in want.kinds]


def _instance(
    rgb: np.ndarray,
    hsv_image: tuple[np.ndarray, np.ndarray, np.ndarray],
    region: Region,
    depth_m: np.ndarray | None = None,
) -> Instance:
    """A colour region with its kind."""
    shape = cues(region.mask, rgb, depth_m)
    kind, scores = classify(shape, region.colour)
    if kind == "platform" and region.colour == "white" and two_shades(shape):  # a light plate on a gray base: a
        region = Region(region.mask, "gray")  # scale is named by its base, every scale's plate is light
    m = region.mask
    return Instance(region, kind, scores, tuple(channel[m] for channel in hsv_image))


def _matching(instances: list[Instance], want: ObjectPhrase, loose: float) -> list[Instance]:
    """The instances a phrase names, best first (see the module docstring)."""
    found = [i for i in instances if want.colour is None or i.region.colour == want.colour]
    if not found and want.colour in LIGHT_NEUTRALS:  # a white object in the shade, a gray one in the light
        found = [i for i in instances if i.region.colour in LIGHT_NEUTRALS]
    kinds = want.kinds
    if kinds is not None:
        exact = [i for i in found if i.kind in kinds]
        fit = {id(i): max(i.scores[k] for k in kinds) for i in found}
        best = max(fit.values(), default=0.0)
        if exact:  # those that read as another kind just as well only when no other does (a dark can, a block)
            found = [i for i in exact if not _tied(i, kinds)] or exact
        elif want.colour is None:  # the shape alone decides: a region that fits it well, if none is of its kind,
            fits = [i for i in found if fit[id(i)] >= max(SHAPE_ONLY_FIT, best - RANK_MARGIN)]
            found = fits or [i for i in found if i.kind in _look_alike(kinds, LOOK_ALIKE)]  # else a look-alike
        elif best >= loose:  # the colour decides; the shape ranks: the best fits (a loose bound) ...
            found = [i for i in found if fit[id(i)] >= max(loose, best - RANK_MARGIN)]
        else:  # ... or all of that colour but those surely of another kind (a chest is no block)
            found = [i for i in found if not _surely_other(i, kinds)] or found
    if want.shade is not None and len(found) > 1:
        found = _of_shade(found, want.shade)
    return sorted(found, key=lambda i: (-_score(i, want), -i.region.area))


def _tied(instance: Instance, kinds: frozenset[str]) -> bool:
    """Whether a region fits some kind other than these (nor one they read as) within TIE_MARGIN of its best fit
    to them: its shape does not tell which it is (a black can's shading unreadable: a block as much as a can)."""
    others = set(instance.scores) - kinds - _look_alike(kinds, LOOK_ALIKE | BODY_APART)
    best = max(instance.scores[k] for k in kinds)
    return max((instance.scores[k] for k in others), default=0.0) >= best - TIE_MARGIN


def _look_alike(kinds: frozenset[str], table: dict[str, frozenset[str]]) -> set[str]:
    """The other kinds an object of these kinds reads as with a part of it unseen (LOOK_ALIKE, BODY_APART)."""
    return set().union(*(table.get(k, ()) for k in kinds)) - kinds


def _surely_other(instance: Instance, kinds: frozenset[str]) -> bool:
    """Whether a region is confidently of a kind the phrase does not name, nor one that kind reads as with a part
    unseen (a bottle's body apart from its neck is surely a can, and may still be the bottle). A speck's kind is
    told by its size alone: a far or half-hidden object of any kind reads as one, so a speck is never surely
    another kind."""
    kind = instance.kind
    if kind in kinds or kind in SIZE_KINDS or kind in _look_alike(kinds, LOOK_ALIKE | BODY_APART):
        return False
    return instance.scores.get(kind, 0.0) >= CONFIDENT_KIND


def _piles(rgb: np.ndarray, others: list[Instance], want: ObjectPhrase) -> list[Instance]:
    """Regions of the named colour that are small parts too, of a plural phrase (its parts heaped in a dustpan,
    half hidden behind a wall): no larger than PILE_AREA_FRAC of the image, and a fragment (at most two parts'
    size), irregular (neither a block's, a can's nor a ball's outline) or no confident other kind: a region that is
    a whole object of another kind is not one of them."""
    out = []
    for i in others:
        frac = i.region.area / i.region.mask.size
        if i.region.colour != want.colour or frac > PILE_AREA_FRAC:
            continue
        c = cues(i.region.mask, rgb)
        irregular = c.rect_fill < PILE_FILL or c.ellipse_iou < PILE_ELLIPSE
        if frac <= FRAGMENT_AREA_FRAC or irregular or max(i.scores.values()) < CONFIDENT_KIND:
            out.append(i)
    return out


def _of_shade(found: list[Instance], shade: str) -> list[Instance]:
    """Among regions of one colour, the paler ("light": saturation well below the deepest's; shading leaves
    saturation alone) or the darker ("dark": value well below the brightest's)."""
    channel = 1 if shade == "light" else 2
    level = {id(i): float(np.median(i.hsv[channel])) for i in found}
    ref = max(level.values())
    kept = [i for i in found if level[id(i)] < SHADE_RATIO * ref]
    return kept or found


def _score(instance: Instance, want: ObjectPhrase) -> float:
    return 1.0 if want.kinds is None else max(instance.scores[k] for k in want.kinds)


def _label(instance: Instance) -> str:
    return f"{instance.region.colour} {instance.kind.replace('_', ' ')}"


def _detection(instance: Instance, want: ObjectPhrase, mask: np.ndarray) -> Detection:
    return Detection(mask, _score(instance, want), box_of(mask), _label(instance))


def _lid(
    rgb: np.ndarray,
    whole: Instance,
    instances: list[Instance],
    want: ObjectPhrase,
    depth_m: np.ndarray | None,
    min_area: int,
) -> np.ndarray | None:
    """The lid of an object: a region of another colour attached to it from above, or else, for a lidded box
    (or a shut one, which looks like a plain box, when the phrase may name a lidded box), the topmost face of its
    own region (a lid of the box's own colour). Where depth is known, a thing of the lid's colour behind the box
    that shares the lid's region in the image is cut off along the depth step (a blue chest behind a blue lid went
    into the lid's mask, and the goal moved both)."""
    lid = _attached_lid(whole, instances, depth_m, any_shape=True)
    if lid is not None:  # less the pixels along the box where the two colours blend (washed out)
        mask = lid.region.mask & ~whole.region.mask
        if depth_m is not None:
            mask = _meeting_pieces(mask, whole.region.mask, depth_m, min_area)
        along = mask & cv2.dilate(whole.region.mask.astype(np.uint8), CROSS).astype(bool)
        _, sat, _ = hsv(rgb)
        return mask & ~(along & (sat < BLEND_SATURATION * np.median(sat[mask])))
    may_be_lidded = want.kinds is None or "lidded_box" in want.kinds
    if _reads_open(whole) or (whole.kind == "box" and may_be_lidded):
        return _top_face(rgb, whole.region.mask)
    return None


def _reads_open(instance: Instance) -> bool:
    """An open chest: classified so, or fitting one confidently while another kind fits a little better (an open
    chest turned so its lid stands over its side reads as a dustpan as well: a scoop with a raised back)."""
    return instance.kind == "lidded_box" or instance.scores.get("lidded_box", 0.0) >= CONFIDENT_KIND


def _inside(mask: np.ndarray, own: np.ndarray) -> bool:
    """Whether `own` lies just above `mask` along most of its top edge: the region is inside that object (screws
    heaped in a dustpan), seen through its open top, not a lid on it (a lid's top edge meets what lies beyond)."""
    v, u = np.nonzero(mask)
    columns = np.unique(u)
    tops = np.array([v[u == c].min() for c in columns])
    covered = np.zeros(len(columns), bool)
    for dv in range(1, ATTACHED_PX + 2):
        covered |= own[np.clip(tops - dv, 0, None), columns]
    return bool(covered.mean() >= ENCLOSED_TOP)


def _attached_lid(
    whole: Instance, instances: list[Instance], depth_m: np.ndarray | None = None, any_shape: bool = False
) -> Instance | None:
    """The largest region touching `whole` from above: over its width, reaching above its middle, covering
    LID_MIN_FRACTION of it, flat unless `any_shape` (a lid seen edge-on looks like anything but a ball), not
    inside it (what lies in an open box is no lid), and meeting it in depth where depth is known (_meets)."""
    own = whole.region.mask
    near = cv2.dilate(own.astype(np.uint8), np.ones((2 * ATTACHED_PX + 1,) * 2, np.uint8)).astype(bool)
    u0, v0, u1, v1 = box_of(own)
    middle = (v0 + v1) / 2

    def lid_like(i: Instance) -> bool:
        a0, b0, a1, b1 = box_of(i.region.mask)
        over = min(a1, u1) - max(a0, u0)
        return (
            (i.kind in FLAT_KINDS or (any_shape and i.kind not in ("sphere", "bowl", "pan")))
            and i.region.area >= LID_MIN_FRACTION * whole.region.area
            and over >= 0.5 * (a1 - a0)
            and (b0 + b1) / 2 < middle
            and bool((i.region.mask & near).any())
            and not _inside(i.region.mask, own)
            and (meets := _meets(i.region.mask, own, depth_m)) is not False
            and _resting_share(i.region.mask, near) >= (LID_RESTS_ON_MEETING if meets else LID_RESTS_ON)
        )

    return max((i for i in instances if i is not whole and lid_like(i)), key=lambda i: i.region.area, default=None)


def _meets(mask: np.ndarray, own: np.ndarray, depth_m: np.ndarray | None) -> bool | None:
    """Whether two regions touching in the image touch in the scene: the median depths along their shared border,
    on either side, within MEET_M. None without depth, or with none known along the border (no evidence)."""
    if depth_m is None:
        return None
    border = np.ones((2 * ATTACHED_PX + 1,) * 2, np.uint8)
    near_own = mask & cv2.dilate(own.astype(np.uint8), border).astype(bool)
    near_mask = own & cv2.dilate(mask.astype(np.uint8), border).astype(bool)
    a, b = depth_m[near_own], depth_m[near_mask]
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    if not (len(a) and len(b)):
        return None
    return abs(float(np.median(a)) - float(np.median(b))) <= MEET_M


def _meeting_pieces(mask: np.ndarray, own: np.ndarray, depth_m: np.ndarray, min_area: int) -> np.ndarray:
    """The pieces of `mask` (cut along depth steps) that touch `own` in the image and meet it in depth; all of
    `mask` when it is one piece or none does."""
    pieces = occlusion_pieces(mask, depth_m, min_area)
    near = cv2.dilate(own.astype(np.uint8), np.ones((2 * ATTACHED_PX + 1,) * 2, np.uint8)).astype(bool)
    meeting = [p for p in pieces if (p & near).any() and _meets(p, own, depth_m) is not False]
    return np.logical_or.reduce(meeting) if 1 <= len(meeting) < len(pieces) else mask


def _resting_share(mask: np.ndarray, near: np.ndarray) -> float:
    """Share of a region's columns whose lowest pixel lies on `near` (an object's region, dilated): a lid is
    hinged on or lies on its box along its whole width; a thing behind the box only peeks out above it in part."""
    v, u = np.nonzero(mask)
    columns = np.unique(u)
    bottoms = np.array([v[u == c].max() for c in columns])
    below = np.clip(bottoms + 1, 0, mask.shape[0] - 1)
    return float((near[bottoms, columns] | near[below, columns]).mean())


def _top_face(rgb: np.ndarray, mask: np.ndarray) -> np.ndarray | None:
    """A lid of the object's own colour: the topmost of the faces (pieces between the edges inside the region)
    covering LID_MIN_FRACTION of it, with all of the region above its lower edge (the line it is hinged on when
    open, the box's front top edge when shut), so the lid's own rim and shading steps stay with it."""
    # edges in the brightest channel (value), not gray: gray weighs blue at a tenth, and a dark blue box's faces
    # differ in gray by less than the edge threshold
    value = np.ascontiguousarray(rgb.max(axis=2))
    edges = cv2.dilate(cv2.Canny(value, 15, 45), np.ones((2, 2), np.uint8)).astype(bool)
    n, comp = cv2.connectedComponents((mask & ~edges).astype(np.uint8), connectivity=4)
    large = [f for f in (comp == i for i in range(1, n)) if f.sum() >= LID_MIN_FRACTION * mask.sum()]
    if not large:
        return None
    face = min(large, key=lambda f: np.nonzero(f)[0].mean())
    if face.sum() > (1.0 - LID_MIN_FRACTION) * mask.sum():  # one face is the whole object: no lid to tell from it
        return None
    v, u = np.nonzero(face)
    columns = np.unique(u)
    bottom = np.array([v[u == c].max() for c in columns], np.float64)
    a, b = np.polyfit(columns, bottom, 1)  # the face's lower edge as a line across the image
    rows, cols = np.nonzero(mask)
    lid = np.zeros_like(mask)
    above = rows <= a * cols + b + 1.0
    lid[rows[above], cols[above]] = True
    # the face alone where its edge is no line across the box: a lid drawn shut askew on it, most of what is seen
    for part, least in ((lid, LID_MIN_FRACTION), (face, SHUT_LID_FRACTION)):
        if least * mask.sum() <= part.sum() < 0.8 * mask.sum():
            return part
    return None
