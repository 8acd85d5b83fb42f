"""The offline instruction grammar: what the default profile understands without a language model.

    place|put|move X (in|into|on|onto|on top of|next to|beside|left of|right of|behind|in front of) Y
    rotate|turn X [by] N (degrees|deg) [clockwise|counterclockwise|anticlockwise]
    stand X up | stand up X
    push X [left|right|forward|backward|away|toward the camera] [by N (cm|mm|m)]
    close X
    sweep X (into|onto|to|in) Y [with Z]
    pick up X | pick X up | lift X [up] [by N (cm|mm|m)]
    take X (off|off of|out of|from) Y

X, Y and Z are object phrases made of colour and shape words ("the red block", "the pan", "the dark blue bottle",
"the lid of the blue box"); only sweep's X may name several ("the screws"); "to the left of" and "to the right
of" are accepted too. Directions are as seen from the camera, on the table plane: left/right along the image,
behind = farther from the camera, in front = nearer. Rotation is counterclockwise seen from above unless
"clockwise" is given. A sweep is done with a tool, Z or else the brush; a lift raises X by 10 cm unless told
and holds it; a take-off lifts X clear of Y and sets it down on the table. A sentence outside the grammar is an
error that quotes the grammar.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from pipeline.perception.offline_segmenter import COLOUR_WORDS, SHAPE_WORDS, parse_phrase, shape_word
from pipeline.perception.segmenter import SegmentationError

Action = Literal["place", "rotate", "stand_up", "push", "close", "sweep", "lift", "take_off"]
DEFAULT_TOOL = "brush"  # what a sweep is done with when the sentence names no tool
DEFAULT_LIFT_M = 0.10
SWEEP_RELATIONS = {"into": "in", "in": "in", "onto": "on", "to": "in"}
OFF_RELATIONS = {"off of": "off", "off": "off", "out of": "out_of", "from": "off"}
RELATIONS: dict[str, str] = {
    "on top of": "on",
    "into": "in",
    "in front of": "in_front_of",
    "to the left of": "left_of",
    "to the right of": "right_of",
    "left of": "left_of",
    "right of": "right_of",
    "next to": "next_to",
    "beside": "next_to",
    "behind": "behind",
    "onto": "on",
    "on": "on",
    "in": "in",
}
PUSH_DIRECTIONS: dict[str, str] = {
    "left": "left",
    "right": "right",
    "forward": "away",
    "forwards": "away",
    "away": "away",
    "backward": "toward",
    "backwards": "toward",
    "back": "toward",
    "toward the camera": "toward",
    "towards the camera": "toward",
}
UNITS_M = {"cm": 0.01, "mm": 0.001, "m": 1.0}
GRAMMAR = __doc__.split("\n\n")[1].strip("\n")


class InstructionError(ValueError):
    """The sentence is outside the offline grammar; the message quotes the grammar."""


@dataclass(frozen=True)
class Instruction:
    action: Action
    target: str  # object phrase X, normalised ("red block")
    relation: str | None = None  # place: on, in, next_to, left_of, right_of, behind, in_front_of
    reference: str | None = None  # place: object phrase Y
    angle_deg: float | None = None  # rotate: counterclockwise seen from above
    direction: str | None = None  # push: left, right, away, toward
    distance_m: float | None = None  # push, lift
    tool: str | None = None  # sweep: what it is done with

    @property
    def group(self) -> bool:
        """The target phrase names several objects (a sweep's "screws")."""
        return parse_phrase(self.target).plural

    def canonical(self) -> str:
        """The instruction re-written in the grammar (used as the offline editing prompt)."""
        if self.action == "place":
            return f"put the {self.target} {self.relation.replace('_', ' ')} the {self.reference}"
        if self.action == "rotate":
            return f"rotate the {self.target} by {self.angle_deg:g} degrees"
        if self.action == "stand_up":
            return f"stand the {self.target} up"
        if self.action == "push":
            direction = {"away": "forward", "toward": "backward"}.get(self.direction, self.direction)
            return f"push the {self.target} {direction} by {self.distance_m * 100:g} cm"
        if self.action == "sweep":
            into = {"in": "into", "on": "onto"}[self.relation]
            return f"sweep the {self.target} {into} the {self.reference} with the {self.tool}"
        if self.action == "lift":
            return f"lift the {self.target} by {self.distance_m * 100:g} cm"
        if self.action == "take_off":
            return f"take the {self.target} {'out of' if self.relation == 'out_of' else 'off'} the {self.reference}"
        return f"close the {self.target}"


def _phrase(text: str, sentence: str, several: bool = False) -> str:
    """The object phrase normalised (its shade, colour and shape words as written); one object unless `several`."""
    try:
        p = parse_phrase(text)
    except SegmentationError as e:
        raise InstructionError(f"{sentence!r}: {e}\n{GRAMMAR}") from None
    if p.plural and not several:
        raise InstructionError(
            f"{sentence!r}: {text!r} names several objects; the offline grammar moves one at a time (only a "
            f"sweep takes several)\n{GRAMMAR}"
        )
    return " ".join(w for w in (p.shade, p.colour, _shape_word(text)) if w)


def _shape_word(text: str) -> str | None:
    """The shape word as written ("screws" stays plural), skipping a describing one ("dish" of "dish rack")."""
    words = re.findall(r"[a-z]+", text)
    found = [w for w in words if shape_word(w) is not None]
    return found[-1] if len(found) > 1 and found[0] == "dish" else next(iter(found), None)


_REL = "|".join(re.escape(r) for r in sorted(RELATIONS, key=len, reverse=True))
_DIR = "|".join(re.escape(d) for d in sorted(PUSH_DIRECTIONS, key=len, reverse=True))
PATTERNS: tuple[tuple[str, re.Pattern[str]], ...] = (
    ("place", re.compile(rf"^(?:place|put|move) (?P<x>.+?) (?P<rel>{_REL}) (?P<y>.+)$")),
    (
        "rotate",
        re.compile(
            r"^(?:rotate|turn) (?P<x>.+?) (?:by )?(?P<n>-?\d+(?:\.\d+)?) ?(?:degrees|degree|deg|°)"
            r"(?: (?P<sense>clockwise|counterclockwise|anticlockwise|counter-clockwise))?$"
        ),
    ),
    ("stand_up", re.compile(r"^stand (?:up (?P<x1>.+)|(?P<x2>.+?) up)$")),
    (
        "push",
        re.compile(
            rf"^push (?P<x>.+?)(?: (?:to the )?(?P<dir>{_DIR}))?(?: by (?P<n>\d+(?:\.\d+)?) ?(?P<unit>cm|mm|m))?$"
        ),
    ),
    ("close", re.compile(r"^close (?P<x>.+)$")),
    (
        "sweep",
        re.compile(
            rf"^sweep (?P<x>.+?) (?P<rel>{'|'.join(SWEEP_RELATIONS)}) (?P<y>.+?)(?: (?:with|using) (?P<z>.+))?$"
        ),
    ),
    (
        "lift",
        re.compile(
            r"^(?:pick up (?P<x1>.+)|pick (?P<x2>.+?) up|lift (?:up )?(?P<x3>.+?)(?: up)?"
            r"(?: by (?P<n>\d+(?:\.\d+)?) ?(?P<unit>cm|mm|m))?)$"
        ),
    ),
    ("take_off", re.compile(r"^take (?P<x>.+?) (?P<rel>off of|off|out of|from) (?P<y>.+)$")),
)


def lid_of(phrase: str) -> str:
    """The phrase naming the part that moves when an object is closed (the offline segmenter's part grammar)."""
    return f"lid of the {phrase}"


def check_instruction(sentence: str) -> Instruction:
    """The sentence parsed, or InstructionError quoting the grammar: cheap (no image, no model), so a command line
    can refuse a sentence before anything starts."""
    try:
        return parse_instruction(sentence)
    except InstructionError as e:
        message = str(e)
        raise InstructionError(message if GRAMMAR in message else f"{message}\n{GRAMMAR}") from None


def parse_instruction(sentence: str, default_push_m: float = 0.10) -> Instruction:
    """Parse one sentence of the offline grammar (case and a final full stop do not matter)."""
    text = " ".join(sentence.lower().strip().rstrip(".!").split())
    for action, pattern in PATTERNS:
        m = pattern.match(text)
        if m is None:
            continue
        g = m.groupdict()
        if action == "place":
            return Instruction("place", _phrase(g["x"], sentence), RELATIONS[g["rel"]], _phrase(g["y"], sentence))
        if action == "rotate":
            angle = float(g["n"]) * (-1.0 if g["sense"] == "clockwise" else 1.0)
            return Instruction("rotate", _phrase(g["x"], sentence), angle_deg=angle)
        if action == "stand_up":
            return Instruction("stand_up", _phrase(g["x1"] or g["x2"], sentence))
        if action == "push":
            dist = float(g["n"]) * UNITS_M[g["unit"]] if g["n"] else default_push_m
            if not 0.0 < dist <= 0.5:
                raise InstructionError(f"{sentence!r}: push distance {dist:.3f} m outside (0, 0.5] m")
            direction = PUSH_DIRECTIONS[g["dir"]] if g["dir"] else "away"
            return Instruction("push", _phrase(g["x"], sentence), direction=direction, distance_m=dist)
        if action == "sweep":
            tool = _phrase(g["z"], sentence) if g["z"] else DEFAULT_TOOL
            target = _phrase(g["x"], sentence, several=True)
            return Instruction("sweep", target, SWEEP_RELATIONS[g["rel"]], _phrase(g["y"], sentence), tool=tool)
        if action == "lift":
            dist = float(g["n"]) * UNITS_M[g["unit"]] if g["n"] else DEFAULT_LIFT_M
            if not 0.02 <= dist <= 0.3:
                raise InstructionError(f"{sentence!r}: lift height {dist:.3f} m outside [0.02, 0.3] m")
            return Instruction("lift", _phrase(g["x1"] or g["x2"] or g["x3"], sentence), distance_m=dist)
        if action == "take_off":
            return Instruction(
                "take_off", _phrase(g["x"], sentence), OFF_RELATIONS[g["rel"]], _phrase(g["y"], sentence)
            )
        return Instruction("close", _phrase(g["x"], sentence))
    raise InstructionError(f"{sentence!r} is not in the offline instruction grammar:\n{GRAMMAR}")


def with_colour_found(phrase: str, label: str) -> str:
    """The phrase with the colour its object was found in (a detection's label, e.g. 'cyan cylinder') when it
    names none: 'the cylinder' -> 'the cyan cylinder', 'lid of the chest' -> 'lid of the yellow chest'. The object
    is found again in the goal image, at the second look and after execution, where it stands elsewhere or turned
    and its silhouette may no longer say its kind; with a colour the colour decides and the shape only ranks. A
    label without a colour word (a model backend's, which echoes the phrase) leaves the phrase as it is."""
    words = phrase.split()
    if any(w.lower() in COLOUR_WORDS for w in words):
        return phrase
    colour = next((w for w in re.findall(r"[a-z]+", label.lower()) if w in COLOUR_WORDS), None)
    shapes = [k for k, w in enumerate(words) if w.lower() in SHAPE_WORDS]
    if colour is None or not shapes:
        return phrase
    return " ".join([*words[: shapes[-1]], colour, *words[shapes[-1] :]])
