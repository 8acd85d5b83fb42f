"""What each object kind of the simulator is for generated scenes: the range of its sizes, the words a person
uses for it, and what it can take part in (grasped and placed, a support, a container, stood up, closed).

One table, so a new kind (a brush, a dish rack) is one entry here plus its MJCF in scene.py; the generator and
its instructions pick it up from its roles.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

Rng = np.random.Generator
# roles: graspable (picked up and placed), pushable, rotatable (a turn about the vertical is visible), support
# (things go on it), container (things go in it), lying (stood up), closable (its lid shuts), sweepable (a small
# part swept with others), tool (held to move other things)
ROLES = ("graspable", "pushable", "rotatable", "support", "container", "lying", "closable", "sweepable", "tool")
DENSITY_KG_M3 = 500.0  # wood or filled plastic


@dataclass(frozen=True)
class KindSpec:
    """A kind of object: `sample(rng)` gives its SceneObject fields (sizes, pose options) without name, colour or
    position; `nouns` are what a person calls it; `roles(fields)` what it can do with those sizes."""

    kind: str
    nouns: tuple[str, ...]
    sample: Callable[[Rng], dict]
    roles: Callable[[dict], frozenset[str]]
    large: bool = False  # takes much of the table (at most a few per scene)
    generated: bool = True  # drawn by the scene generator (the task kinds are placed by their scenes only, so
    # adding them left every generated case as it was)


def _u(rng: Rng, lo: float, hi: float, digits: int = 3) -> float:
    return round(float(rng.uniform(lo, hi)), digits)


def _mass(volume_m3: float) -> float:
    return round(float(np.clip(DENSITY_KG_M3 * volume_m3, 0.03, 0.3)), 3)


def _box(rng: Rng) -> dict:
    size = (_u(rng, 0.03, 0.065), _u(rng, 0.03, 0.065), _u(rng, 0.03, 0.075))
    return {"size_m": size, "mass_kg": _mass(size[0] * size[1] * size[2])}


def _box_roles(f: dict) -> frozenset[str]:
    sx, sy, _ = f["size_m"]
    roles = {"graspable", "pushable", "rotatable"}
    if min(sx, sy) >= 0.05:  # a block wide enough to stack another on
        roles.add("support")
    return frozenset(roles)


def _cylinder(rng: Rng) -> dict:
    if rng.uniform() < 0.35:  # on its side: long enough to be stood up
        r, h = _u(rng, 0.02, 0.032), _u(rng, 0.09, 0.14)
        return {"radius_m": r, "height_m": h, "lying": True, "mass_kg": _mass(np.pi * r * r * h)}
    r, h = _u(rng, 0.02, 0.038), _u(rng, 0.05, 0.12)
    return {"radius_m": r, "height_m": h, "mass_kg": _mass(np.pi * r * r * h)}


def _upright_or_lying(upright: set[str]) -> Callable[[dict], frozenset[str]]:
    return lambda f: frozenset({"lying", "rotatable"} if f.get("lying") else upright)


def _sphere(rng: Rng) -> dict:
    r = _u(rng, 0.025, 0.04)
    return {"radius_m": r, "mass_kg": _mass(4 / 3 * np.pi * r**3)}


def _bottle(rng: Rng) -> dict:
    r, h = _u(rng, 0.025, 0.034), _u(rng, 0.15, 0.22)
    return {"radius_m": r, "height_m": h, "lying": bool(rng.uniform() < 0.7), "mass_kg": _mass(0.4 * np.pi * r * r * h)}


def _plate(rng: Rng) -> dict:
    return {"radius_m": _u(rng, 0.07, 0.10), "height_m": _u(rng, 0.012, 0.02), "fixed": True}


def _pan(rng: Rng) -> dict:
    return {"radius_m": _u(rng, 0.07, 0.10), "height_m": _u(rng, 0.03, 0.05)}


def _bowl(rng: Rng) -> dict:
    return {"radius_m": _u(rng, 0.06, 0.095), "height_m": _u(rng, 0.04, 0.09)}


def _platform(rng: Rng) -> dict:
    return {"size_m": (_u(rng, 0.08, 0.12), _u(rng, 0.08, 0.12), _u(rng, 0.02, 0.04))}


def _lidded_box(rng: Rng) -> dict:
    return {
        "size_m": (_u(rng, 0.10, 0.13), _u(rng, 0.12, 0.17), _u(rng, 0.05, 0.08)),
        "lid_open_deg": round(float(rng.uniform(80, 105)), 1),
    }


def _cup(rng: Rng) -> dict:
    r, h = _u(rng, 0.026, 0.034), _u(rng, 0.07, 0.1)
    return {"radius_m": r, "height_m": h, "mass_kg": _mass(0.3 * np.pi * r * r * h)}


def _screw(rng: Rng) -> dict:
    return {"radius_m": _u(rng, 0.005, 0.007, 4), "height_m": _u(rng, 0.04, 0.05), "mass_kg": 0.012}


def _brush(rng: Rng) -> dict:
    return {"size_m": (_u(rng, 0.045, 0.055), _u(rng, 0.10, 0.13), 0.03), "mass_kg": 0.18}


def _dustpan(rng: Rng) -> dict:
    return {"size_m": (_u(rng, 0.13, 0.16), _u(rng, 0.22, 0.28), _u(rng, 0.02, 0.03))}


def _dish_rack(rng: Rng) -> dict:
    return {"size_m": (_u(rng, 0.12, 0.18), _u(rng, 0.16, 0.18), _u(rng, 0.05, 0.07))}


def _stand(rng: Rng) -> dict:
    side = _u(rng, 0.1, 0.14)
    return {"size_m": (side, side, _u(rng, 0.07, 0.11))}


KINDS: dict[str, KindSpec] = {
    s.kind: s
    for s in (
        KindSpec("box", ("block", "cube", "box"), _box, _box_roles),
        KindSpec("cylinder", ("cylinder", "can"), _cylinder, _upright_or_lying({"graspable", "pushable"})),
        KindSpec("sphere", ("ball", "sphere"), _sphere, lambda f: frozenset({"graspable"})),
        KindSpec("bottle", ("bottle",), _bottle, _upright_or_lying({"graspable"})),
        KindSpec("plate", ("plate", "dish"), _plate, lambda f: frozenset({"support"}), large=True),
        KindSpec("pan", ("pan",), _pan, lambda f: frozenset({"container"}), large=True),
        KindSpec("bowl", ("bowl",), _bowl, lambda f: frozenset({"container"}), large=True),
        KindSpec("platform", ("scale", "platform"), _platform, lambda f: frozenset({"support"}), large=True),
        KindSpec("lidded_box", ("box", "chest"), _lidded_box, lambda f: frozenset({"closable"}), large=True),
        KindSpec("cup", ("cup", "mug"), _cup, lambda f: frozenset({"graspable"}), generated=False),
        KindSpec("screw", ("screw", "bolt"), _screw, lambda f: frozenset({"sweepable"}), generated=False),
        KindSpec("brush", ("brush",), _brush, lambda f: frozenset({"tool"}), large=True, generated=False),
        KindSpec("dustpan", ("dustpan",), _dustpan, lambda f: frozenset({"container"}), large=True, generated=False),
        KindSpec("dish_rack", ("rack",), _dish_rack, lambda f: frozenset({"support"}), large=True, generated=False),
        KindSpec("stand", ("stand", "shelf"), _stand, lambda f: frozenset({"support"}), large=True, generated=False),
    )
}
GENERATED_KINDS = tuple(k for k, spec in KINDS.items() if spec.generated)
# what a noun names: "box" is any box, a lidded one too; "block" and "cube" only a plain one
NOUN_KINDS: dict[str, frozenset[str]] = {}
for _spec in KINDS.values():
    for _noun in _spec.nouns:
        NOUN_KINDS[_noun] = NOUN_KINDS.get(_noun, frozenset()) | {_spec.kind}


def half_extent(fields: dict, kind: str) -> float:
    """Half the largest horizontal extent of an object [m] (what must fit on a support or in a container)."""
    if fields.get("size_m") is not None:
        return 0.5 * float(np.hypot(*fields["size_m"][:2]))
    if fields.get("lying"):
        return 0.5 * max(fields["height_m"], 2 * fields["radius_m"])
    return float(fields["radius_m"])


def room_on(fields: dict, kind: str) -> float:
    """Radius of the free area on a support or in a container [m]: a placed object must fit within it."""
    if kind in ("plate", "pan", "bowl"):
        return float(fields["radius_m"]) - 0.008
    if kind == "dustpan":  # its floor, less the walls
        return 0.5 * min(fields["size_m"][:2]) - 0.02
    if kind == "platform":
        return 0.45 * min(fields["size_m"][:2])  # its weighing plate
    return 0.5 * min(fields["size_m"][:2])
