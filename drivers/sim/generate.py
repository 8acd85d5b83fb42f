"""Seeded random scenes with instructions, for runs on scenes nobody tuned on.

`generate_case(seed)` builds a scene of 2-7 objects of the simulator's kinds (kinds.py) with colours over the
named palette (shades included; not brown, the table's own wood), sizes across each kind's range, placed anywhere
in the arm's reach and the camera's view with their true footprints apart, and an instruction for one action
(the seed picks it: placing on, in or beside, rotating, pushing, standing up, closing, or a sentence outside the
offline grammar). `case.tasks` lists an instruction for every action the scene offers. The words are what a
person would say (kinds.NOUN_KINDS), chosen so each phrase names exactly one object; whether a backend
understands them is what the runs measure. A task names only objects the camera shows (sight.py: most of their
top in sight past the others; a block behind an open chest's lid is named by no task).

`goalvla run --scene gen:SEED` runs the scene of `generate_case(SEED)`; `scene_for(sim)` resolves scene names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from drivers.config import SimCameraConfig, SimConfig
from drivers.sim.footprint import footprint_gap
from drivers.sim.kinds import GENERATED_KINDS, KINDS, NOUN_KINDS, half_extent, room_on
from drivers.sim.scene import (
    COLORS,
    Randomisation,
    Scene,
    SceneError,
    SceneObject,
    expand_groups,
    load_scene,
    place,
    placed_footprint,
)
from drivers.sim.sight import share_in_sight

GENERATED_PREFIX = "gen:"
REACH_M = (0.30, 0.62)  # object centres from the base axis: grasps, lifts and the goals beside them stay in reach
BEARING_DEG = 42.0  # either side of straight ahead (+x)
VIEW_MAX_X_M = 0.78  # the table edge of the camera's view (its lower image border) is at x = 0.84 m
VIEW_MAX_Y_M = 0.62
GAP_M = 0.03  # free table between footprints: room for the fingers
MIN_IN_SIGHT = 0.5  # a task names an object only when the camera sees at least this share of its top
PLACE_TRIES = 400
# every named colour the camera shows as itself: not brown (the table's own wood) nor dark orange (brown too), nor
# light orange (its lit faces come out yellow)
PALETTE = tuple(c for c in COLORS if c not in ("brown", "dark_orange", "light_orange"))
SHADE_WORDS = ("dark", "light")
# the case's action, cycled by seed so any run of consecutive seeds covers them all
CASE_ACTIONS = (
    "place_on",
    "place_beside",
    "rotate",
    "place_in",
    "push",
    "place_beside",
    "stand_up",
    "place_on",
    "close",
    "place_beside",
    "push",
    "outside",
)
SIDE_RELATIONS = ("next to", "left of", "right of", "behind", "in front of")
PUSH_WORDS = {"left": "left", "right": "right", "forward": "away", "backward": "toward"}
OUTSIDE_GRAMMAR = (
    "wipe the table",
    "sort the objects by colour",
    "shake {x}",
    "throw {x} away",
    "pour {x} over {y}",
)


@dataclass(frozen=True)
class Task:
    """One instruction about a scene: `action` is place, rotate, stand_up, push, close, or outside (a sentence
    outside the offline grammar, to be refused); `target`/`reference` are scene object names."""

    instruction: str
    action: str
    target: str | None = None
    reference: str | None = None
    relation: str | None = None

    @property
    def in_grammar(self) -> bool:
        return self.action != "outside"


@dataclass(frozen=True)
class Case:
    seed: int
    scene: Scene
    task: Task  # the case's instruction
    tasks: tuple[Task, ...]  # one per action and object the scene offers

    @property
    def scene_name(self) -> str:
        return f"{GENERATED_PREFIX}{self.seed}"


def family(colour: str) -> str:
    """The colour's name without its shade: dark_blue -> blue."""
    return colour.split("_", 1)[1] if colour.split("_", 1)[0] in SHADE_WORDS else colour


def _matches(o: SceneObject, colour: str | None, noun: str | None) -> bool:
    return (colour is None or family(o.color) == colour) and (noun is None or o.kind in NOUN_KINDS[noun])


def phrases(scene: Scene, name: str) -> list[str]:
    """Every phrase naming exactly this object among the scene's: colour and noun, shade too, or the noun alone."""
    o = next(x for x in scene.objects if x.name == name)
    out = []
    for noun in KINDS[o.kind].nouns:
        if sum(_matches(x, None, noun) for x in scene.objects) == 1:
            out.append(f"the {noun}")
        if sum(_matches(x, family(o.color), noun) for x in scene.objects) == 1:
            out.append(f"the {family(o.color)} {noun}")
            if o.color != family(o.color):
                out.append(f"the {o.color.replace('_', ' ')} {noun}")
    return out


# -- scenes -------------------------------------------------------------------------------------------------
def _fields(o: SceneObject) -> dict:
    return o.model_dump(exclude_none=True)


def _roles(o: SceneObject) -> frozenset[str]:
    return KINDS[o.kind].roles(_fields(o))


def _fits(item: SceneObject, holder: SceneObject) -> bool:
    return half_extent(_fields(item), item.kind) <= room_on(_fields(holder), holder.kind)


def _draw(rng: np.random.Generator, kind: str, name: str, **fixed) -> SceneObject:
    fields = KINDS[kind].sample(rng) | fixed
    colour = str(rng.choice(PALETTE))
    if kind == "lidded_box":  # the lid: a darker shade of the box (default), the box's own colour, or another one
        fields.setdefault("lid_color", [None, colour, str(rng.choice(PALETTE))][int(rng.integers(3))])
        fields = {k: v for k, v in fields.items() if v is not None}
    return SceneObject(name=name, kind=kind, color=colour, xy_m=(0.0, 0.0), **fields)


def _draw_with(rng: np.random.Generator, kinds: tuple[str, ...], role: str, name: str, tries: int = 50) -> SceneObject:
    for _ in range(tries):
        o = _draw(rng, str(rng.choice(kinds)), name)
        if role in _roles(o):
            return o
    raise SceneError(f"no {role} object among {kinds} in {tries} draws")


def _required(rng: np.random.Generator, action: str) -> list[SceneObject]:
    """The objects the action needs: the target first, then its reference."""
    graspable = ("box", "cylinder", "sphere", "bottle")
    if action == "place_on":
        support = _draw_with(rng, ("plate", "platform", "box"), "support", "ref")
        for _ in range(50):
            target = _draw_with(rng, graspable, "graspable", "target")
            if _fits(target, support):
                return [target, support]
        return [_draw(rng, "sphere", "target", radius_m=0.025), support]
    if action == "place_in":
        container = _draw_with(rng, ("bowl", "pan"), "container", "ref")
        for _ in range(50):
            target = _draw_with(rng, ("box", "cylinder", "sphere"), "graspable", "target")
            if _fits(target, container):
                return [target, container]
        return [_draw(rng, "sphere", "target", radius_m=0.025), container]
    if action == "place_beside":
        return [_draw_with(rng, graspable, "graspable", "target"), _draw(rng, str(rng.choice(GENERATED_KINDS)), "ref")]
    if action == "rotate":
        return [_draw_with(rng, ("box", "box", "bottle", "cylinder"), "rotatable", "target")]
    if action == "push":
        return [_draw_with(rng, ("box", "cylinder"), "pushable", "target")]
    if action == "stand_up":
        return [_draw_with(rng, ("bottle", "cylinder"), "lying", "target")]
    if action == "close":
        return [_draw(rng, "lidded_box", "target")]
    return [_draw(rng, str(rng.choice(graspable)), "target")]


def _in_reach_and_view(o: SceneObject, pose: tuple[float, float, float]) -> bool:
    x, y, _ = pose
    r, bearing = math.hypot(x, y), math.degrees(math.atan2(y, x))
    if not REACH_M[0] <= r <= REACH_M[1] or abs(bearing) > BEARING_DEG:
        return False
    corners = np.concatenate(placed_footprint(o, pose))
    return bool(corners[:, 0].max() <= VIEW_MAX_X_M and np.abs(corners[:, 1]).max() <= VIEW_MAX_Y_M)


def _random_pose(rng: np.random.Generator) -> tuple[float, float, float]:
    r = math.sqrt(rng.uniform(REACH_M[0] ** 2, REACH_M[1] ** 2))  # uniform over the area
    bearing = math.radians(rng.uniform(-BEARING_DEG, BEARING_DEG))
    return r * math.cos(bearing), r * math.sin(bearing), float(rng.uniform(-math.pi, math.pi))


def _yaw_range(o: SceneObject) -> float | None:
    """A lidded box keeps its hinge roughly at the back (an open lid facing the camera would hide the box)."""
    return math.radians(45.0) if o.kind == "lidded_box" else None


def _place_all(rng: np.random.Generator, objects: list[SceneObject]) -> list[SceneObject] | None:
    """Each object at a random pose in reach and view whose footprint keeps GAP_M from those placed before."""
    placed: list[tuple[SceneObject, list[np.ndarray]]] = []
    out = []
    for o in objects:
        for _ in range(PLACE_TRIES):
            x, y, yaw = _random_pose(rng)
            limit = _yaw_range(o)
            if limit is not None:
                yaw = float(rng.uniform(-limit, limit))
            pose = (x, y, yaw)
            if not _in_reach_and_view(o, pose):
                continue
            outline = placed_footprint(o, pose)
            if all(footprint_gap(outline, other) >= GAP_M for _, other in placed):
                break
        else:
            return None
        placed.append((o, outline))
        out.append(o.model_copy(update={"xy_m": (round(x, 4), round(y, 4)), "yaw_deg": round(math.degrees(yaw), 2)}))
    return out


def _distinguishable(objects: list[SceneObject], names: tuple[str, ...]) -> bool:
    scene = Scene(name="check", objects=tuple(objects))
    return all(phrases(scene, n) for n in names)


def generate_scene(seed: int) -> Scene:
    """The scene of case `seed` (see generate_case)."""
    return _generate(seed)[0]


def _generate(seed: int) -> tuple[Scene, str, np.random.Generator]:
    rng = np.random.default_rng([seed, 15])
    action = CASE_ACTIONS[seed % len(CASE_ACTIONS)]
    for _ in range(20):
        required = _required(rng, action)
        n = int(rng.integers(max(2, len(required)), 8))
        objects = list(required)
        large = sum(KINDS[o.kind].large for o in objects)
        while len(objects) < n:
            kind = str(rng.choice(GENERATED_KINDS))
            if KINDS[kind].large and large >= 2:
                continue
            large += KINDS[kind].large
            objects.append(_draw(rng, kind, f"o{len(objects)}"))
        names = tuple(o.name for o in required)
        for i in range(len(required), len(objects)):  # recolour a distractor that makes the target ambiguous
            for _ in range(20):
                if _distinguishable(objects[: i + 1], names):
                    break
                objects[i] = objects[i].model_copy(update={"color": str(rng.choice(PALETTE))})
        if not _distinguishable(objects, names):
            continue
        placed = _place_all(rng, objects)
        if placed is None:
            continue
        named = [o.model_copy(update={"name": f"{o.color}_{o.kind}_{i}"}) for i, o in enumerate(placed)]
        scene = Scene(
            name=f"{GENERATED_PREFIX}{seed}",
            description=f"generated scene {seed} ({action})",
            objects=tuple(named),
            randomise=Randomisation(xy_jitter_m=0.0, yaw_jitter_deg=0.0, min_gap_m=GAP_M - 0.005),
        )
        return scene, action, rng
    raise SceneError(f"generated scene {seed}: no placement of its objects in reach and view in 20 attempts")


# -- instructions -------------------------------------------------------------------------------------------
def _say(rng: np.random.Generator, scene: Scene, name: str) -> str:
    options = phrases(scene, name)
    return str(options[int(rng.integers(len(options)))])


def _directions(camera: SimCameraConfig) -> dict[str, np.ndarray]:
    """Push directions on the table as seen from the camera: right along the image, forward away from it."""
    forward = np.array(camera.look_at_m[:2]) - np.array(camera.position_m[:2])
    forward /= np.linalg.norm(forward)
    right = np.array([forward[1], -forward[0]])  # image x = viewing direction x up
    return {"left": -right, "right": right, "forward": forward, "backward": -forward}


def _free_after_push(scene: Scene, o: SceneObject, shift: np.ndarray) -> bool:
    pose = (o.xy_m[0] + shift[0], o.xy_m[1] + shift[1], math.radians(o.yaw_deg))
    if not _in_reach_and_view(o, pose):
        return False
    outline = placed_footprint(o, pose)
    return all(footprint_gap(outline, placed_footprint(x, _pose(x))) >= 0.02 for x in scene.objects if x.name != o.name)


def _pose(o: SceneObject) -> tuple[float, float, float]:
    return (*o.xy_m, math.radians(o.yaw_deg))


SIDE_GAP_M = 0.04  # a spot beside a reference: this far from its outline
SIDE_TURNS_DEG = (0.0, 20.0, -20.0, 40.0, -40.0)  # ... straight that way, or turned this much


def _room_beside(scene: Scene, o: SceneObject, ref: SceneObject, relation: str, camera: SimCameraConfig) -> bool:
    """Whether a person would see room to put o `relation` the reference: a spot that way from it (or up to 40
    deg off), just clear of its outline, in reach and view, its footprint 2 cm from every other object."""
    directions = _directions(camera)
    ref_xy, o_xy = np.array(ref.xy_m), np.array(o.xy_m)
    side = {"left of": "left", "right of": "right", "behind": "forward", "in front of": "backward"}.get(relation)
    away = (o_xy - ref_xy) / max(float(np.linalg.norm(o_xy - ref_xy)), 1e-9)  # next to: the side it is on
    base = directions[side] if side is not None else away
    outline = np.concatenate(placed_footprint(ref, _pose(ref)))
    others = [placed_footprint(x, _pose(x)) for x in scene.objects if x.name not in (o.name, ref.name)]
    others.append(placed_footprint(ref, _pose(ref)))
    for turn in np.radians(SIDE_TURNS_DEG):
        c, s = math.cos(turn), math.sin(turn)
        d = np.array([c * base[0] - s * base[1], s * base[0] + c * base[1]])
        reach = float(np.max((outline - ref_xy) @ d))
        xy = ref_xy + d * (reach + SIDE_GAP_M + half_extent(_fields(o), o.kind))
        pose = (float(xy[0]), float(xy[1]), math.radians(o.yaw_deg))
        if not _in_reach_and_view(o, pose):
            continue
        spot = placed_footprint(o, pose)
        if all(footprint_gap(spot, other) >= 0.02 for other in others):
            return True
    return False


def _in_sight(scene: Scene, o: SceneObject, camera: SimCameraConfig) -> bool:
    """Whether the camera shows most of the object (a camera on the arm: taken as seen, its view moves)."""
    return camera.mount != "world" or share_in_sight(scene, o.name, np.array(camera.position_m)) >= MIN_IN_SIGHT


def _tasks_of(rng: np.random.Generator, scene: Scene, camera: SimCameraConfig) -> list[Task]:
    """One task per action and object (and pair) the scene offers, of the objects in sight; phrases chosen at
    random among the unique."""
    named = [o for o in scene.objects if phrases(scene, o.name) and _in_sight(scene, o, camera)]
    tasks: list[Task] = []
    for o in named:
        roles = _roles(o)

        def x(name: str = o.name) -> str:  # a fresh wording per task
            return _say(rng, scene, name)

        if "graspable" in roles:
            for ref in named:
                if ref.name == o.name:
                    continue
                ref_roles = _roles(ref)
                if "support" in ref_roles and _fits(o, ref):
                    tasks.append(Task(f"put {x()} on {_say(rng, scene, ref.name)}", "place", o.name, ref.name, "on"))
                if "container" in ref_roles and _fits(o, ref):
                    tasks.append(Task(f"put {x()} in {_say(rng, scene, ref.name)}", "place", o.name, ref.name, "in"))
                relations = [str(r) for r in rng.permutation(SIDE_RELATIONS)]
                relation = next((r for r in relations if _room_beside(scene, o, ref, r, camera)), None)
                verb = str(rng.choice(("put", "place", "move")))
                if relation is not None:  # a person asks for a place there is room for
                    phrase = f"{verb} {x()} {relation} {_say(rng, scene, ref.name)}"
                    tasks.append(Task(phrase, "place", o.name, ref.name, relation))
        if "rotatable" in roles:
            angle = int(rng.choice((30, 45, 60, 90)))
            sense = str(rng.choice(("", " clockwise", " counterclockwise")))
            tasks.append(Task(f"rotate {x()} by {angle} degrees{sense}", "rotate", o.name))
        if "pushable" in roles:
            for word in rng.permutation(list(PUSH_WORDS)):
                cm = int(rng.integers(4, 13))
                if _free_after_push(scene, o, _directions(camera)[str(word)] * cm / 100):
                    tasks.append(Task(f"push {x()} {word} by {cm} cm", "push", o.name))
                    break
        if "lying" in roles:
            tasks.append(Task(f"stand {x()} up", "stand_up", o.name))
        if "closable" in roles:
            tasks.append(Task(f"close {x()}", "close", o.name))
    for template in OUTSIDE_GRAMMAR:
        a, b = (named + named)[:2] if named else (None, None)
        if a is not None and b is not None:
            text = template.format(x=_say(rng, scene, a.name), y=_say(rng, scene, b.name))
            tasks.append(Task(text, "outside"))
    return tasks


def _main_task(tasks: list[Task], action: str, target: str, reference: str | None) -> Task | None:
    wanted = {
        "place_on": ("place", ("on",)),
        "place_in": ("place", ("in",)),
        "place_beside": ("place", SIDE_RELATIONS),
    }.get(action, (action, None))
    for t in tasks:
        if t.action != wanted[0]:
            continue
        if action == "outside" or (
            t.target == target and (wanted[1] is None or (t.relation in wanted[1] and t.reference == reference))
        ):
            return t
    return None


def generate_case(seed: int, camera: SimCameraConfig | None = None) -> Case:
    """Scene, instruction and action of case `seed`: the same seed gives the same case on every machine."""
    scene, action, rng = _generate(seed)
    target, reference = scene.objects[0].name, scene.objects[1].name  # the action's objects come first
    tasks = _tasks_of(rng, scene, camera or SimCameraConfig())
    main = _main_task(tasks, action, target, reference)
    if main is None:  # e.g. every push from where the target stands runs into a neighbour: any task of the scene
        main = next(t for t in tasks if t.in_grammar)
    return Case(seed, scene, main, tuple(tasks))


# -- scene names --------------------------------------------------------------------------------------------
def scene_for(sim: SimConfig) -> Scene:
    """The scene a sim profile names: `gen:SEED` (a generated scene), a path to a scene YAML (`*.yaml`), or a name
    in the profile's scenes folder."""
    name = sim.scene
    if name.startswith(GENERATED_PREFIX):
        seed = name.removeprefix(GENERATED_PREFIX)
        if not seed.isdigit():
            raise SceneError(f"scene {name!r}: a generated scene is gen:SEED with SEED a non-negative integer")
        return generate_scene(int(seed))
    if name.endswith((".yaml", ".yml")):
        return load_scene(Path(name))
    return load_scene(sim.scene_file)


def check_scene(sim: SimConfig) -> Scene:
    """The profile's scene, loaded and placed as SimWorld will (no simulator): SceneError names what is wrong."""
    scene = expand_groups(scene_for(sim), sim.seed)
    place(scene, sim.seed)
    return scene


def scene_yaml(scene: Scene) -> str:
    """The scene as a scene file (configs/scenes format) that loads back to the same scene."""
    data = scene.model_dump(mode="json", exclude_defaults=True)
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
