"""Scene files (configs/scenes/*.yaml): the objects on the table, validated, placed by seed, written as MJCF.

Object kinds: box, cylinder, sphere, plate, bottle (optionally lying on its side), pan, bowl, platform (a small
scale), lidded_box (a box whose lid is hinged at the back), cup (an open cylinder), and the tasks' furniture and
tools: screw (a small lying cylinder with a head), brush (a bristle head with a raised handle), dustpan (a low
scoop: floor, a ramp lip at its open +x side, walls on the other three), dish_rack (a tray with two rows of tines
that hold plates on their rim), stand (a board on four legs). Static objects are welded to the table. An object
may stand on a static one (`support`) (a block on a stand, a plate in a rack): its pose is then in the support's frame,
at the support's top. A scene's `groups` scatter a seeded number of like objects in a patch (the screws).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, ValidationError

from drivers.config import StrictModel
from drivers.files import InputFileError, load_yaml
from drivers.sim.footprint import disc, footprint_gap, moved, rectangle

BASE_COLORS: dict[str, tuple[float, float, float]] = {
    "red": (0.85, 0.12, 0.10),
    "green": (0.15, 0.65, 0.20),
    "blue": (0.12, 0.30, 0.85),
    "yellow": (0.95, 0.82, 0.10),
    "orange": (0.95, 0.50, 0.10),
    "purple": (0.55, 0.20, 0.70),
    "white": (0.92, 0.92, 0.90),
    "black": (0.08, 0.08, 0.08),
    "gray": (0.45, 0.45, 0.47),
    "brown": (0.50, 0.32, 0.18),
    "pink": (0.95, 0.55, 0.70),
    "cyan": (0.10, 0.75, 0.80),
}
# shades of the chromatic colours: "dark_blue" is blue at 55 % of its brightness, "light_blue" blue 25 % of the way
# to white; a shade keeps its colour's name (a dark blue block is a blue block)
SHADED = ("red", "green", "blue", "yellow", "orange", "purple", "pink", "cyan")
COLORS: dict[str, tuple[float, float, float]] = (
    BASE_COLORS
    | {f"dark_{n}": tuple(round(0.55 * c, 4) for c in BASE_COLORS[n]) for n in SHADED}
    | {f"light_{n}": tuple(round(c + 0.25 * (1 - c), 4) for c in BASE_COLORS[n]) for n in SHADED}
)
OBJECT_CONTACT = {"contype": "1", "conaffinity": "3"}
OBJECT_FRICTION = "1.0 0.01 0.001"
# sliding, torsional, rolling [m] of what can roll (a ball, a body of revolution on its side): rolling resistance
# like a soft fruit's or a label's; an ideal round body lying on a plane rolls away at the slightest asymmetry of
# its contacts (a lying bottle drifted 33 mm in 15 s without it)
ROLLING_FRICTION = "1.0 0.01 0.003"
PAN_HANDLE_M = (0.14, 0.024, 0.016)  # length, width, thickness; it starts at the pan's rim
WALL_M = 0.008  # pan and bowl walls, lidded box walls and lid
RING_SEGMENTS = 20  # boxes making a pan's or a bowl's circular wall
DEFAULT_HEIGHT_M = {"cylinder": 0.1, "plate": 0.015, "bottle": 0.22, "pan": 0.04, "bowl": 0.07, "cup": 0.09}
CUP_WALL_M = 0.005
CUP_SEGMENTS = 16
SCREW_HEAD = (1.7, 0.18)  # head radius / shank radius, head thickness / screw length
# a screw's thread and hex head roll far worse than a smooth cylinder (rolling resistance [m] like a soft fruit's x3)
SCREW_FRICTION = "1.0 0.01 0.01"
BRUSH_HANDLE_M = (0.15, 0.022, 0.028)  # default handle length, width, thickness; its underside 14 mm up
BRUSH_HANDLE_LIFT_M = 0.014
BRISTLE_FRACTION = 0.55  # of the head's height, from the table up: the bristles, a darker shade
BRISTLE_FRICTION = "0.3 0.005 0.0001"  # bristles slide over the table
DUSTPAN_FLOOR_M = 0.002  # floor thickness (under the table-top filter of the camera cloud)
DUSTPAN_LIP_M = 0.03  # the ramp from the table up to the floor along the open side
DUSTPAN_WALL_M = 0.006
RACK_BASE_M = 0.012  # the dish rack's tray
RACK_TINE_M = 0.006  # square tines
RACK_PITCH_M = 0.03  # tine spacing along the rows: a plate stands midway between two (x = pitch * (k + 1/2))
STAND_BOARD_M = 0.015
STAND_LEG_M = 0.015
GROUP_ATTEMPTS = 50
STATIC_KINDS = ("pan", "bowl", "platform", "lidded_box", "dustpan", "dish_rack", "stand")
KIND_NEEDS = {
    "box": "size_m",
    "platform": "size_m",
    "lidded_box": "size_m",
    "cylinder": "radius_m",
    "sphere": "radius_m",
    "plate": "radius_m",
    "bottle": "radius_m",
    "pan": "radius_m",
    "bowl": "radius_m",
    "cup": "radius_m",
    "screw": "radius_m",
    "brush": "size_m",
    "dustpan": "size_m",
    "dish_rack": "size_m",
    "stand": "size_m",
}


class SceneError(ValueError):
    pass


class SceneObject(StrictModel):
    name: str = Field(pattern=r"^[a-z][a-z0-9_]*$")
    kind: Literal[
        "box",
        "cylinder",
        "sphere",
        "plate",
        "bottle",
        "pan",
        "bowl",
        "platform",
        "lidded_box",
        "cup",
        "screw",
        "brush",
        "dustpan",
        "dish_rack",
        "stand",
    ]
    color: str = "red"
    texture: Literal["none", "checker", "stripes"] = "none"
    size_m: tuple[float, float, float] | None = Field(
        default=None,
        description="box, platform, lidded_box; brush head (depth, width, height); dustpan (depth, width, wall "
        "height); dish_rack (length along its rows, width, tine height); stand (board x, board y, height)",
    )
    radius_m: float | None = Field(
        default=None, gt=0, description="cylinder, sphere, plate, bottle, pan, bowl, cup; screw: its shank"
    )
    height_m: float | None = Field(
        default=None, gt=0, description="cylinder, bottle, pan, bowl, plate, cup; screw length"
    )
    handle_m: tuple[float, float, float] = Field(
        default=BRUSH_HANDLE_M, description="brush: handle length, width, thickness"
    )
    mass_kg: float = Field(default=0.15, gt=0)
    xy_m: tuple[float, float]
    yaw_deg: float = 0.0
    lying: bool = Field(default=False, description="bottle/cylinder on its side, a plate on its rim")
    lid_open_deg: float = Field(default=100.0, ge=0, le=110, description="lidded_box initial lid angle")
    lid_color: str | None = Field(default=None, description="lidded_box lid colour; default a darker body colour")
    fixed: bool | None = Field(default=None, description="welded to the table; default per kind")
    jitter: bool = Field(default=True, description="apply the scene's placement randomisation")
    support: str | None = Field(
        default=None, description="a static object it stands on; xy_m and yaw_deg are then in that object's frame"
    )
    group: str | None = Field(default=None, description="the scene group it was scattered by (set on expansion)")

    def is_fixed(self) -> bool:
        if self.fixed is not None:
            return self.fixed
        return self.kind in STATIC_KINDS

    def top_m(self) -> float | None:
        """Height of what an object put `on` this one stands on [m]; None when nothing can stand on it."""
        if self.kind in ("box", "platform", "stand"):
            return self.size_m[2]
        if self.kind == "dish_rack":
            return RACK_BASE_M
        if self.kind == "plate" and not self.lying:
            return self.height_m or DEFAULT_HEIGHT_M["plate"]
        if self.kind == "dustpan":
            return DUSTPAN_FLOOR_M
        return None

    def footprint(self) -> list[np.ndarray]:
        """The table area the object covers, as convex polygons [m] in its own frame (x, y before the yaw)."""
        if self.kind == "brush":  # the head, and the handle behind it (-x)
            dx, dy, _ = self.size_m
            length, width, _ = self.handle_m
            return [
                rectangle(-dx / 2, dx / 2, -dy / 2, dy / 2),
                rectangle(-dx / 2 - length, -dx / 2, -width / 2, width / 2),
            ]
        if self.kind == "screw":  # lying along x, the head at +x
            h, r = self.height_m, self.radius_m * SCREW_HEAD[0]
            return [rectangle(-h / 2, h / 2, -r, r)]
        if self.kind in ("box", "platform", "dustpan", "dish_rack", "stand"):
            sx, sy, _ = self.size_m
            return [rectangle(-sx / 2, sx / 2, -sy / 2, sy / 2)]
        if self.kind == "lidded_box":  # an open lid leaning past upright reaches behind the box
            sx, sy, _ = self.size_m
            behind = min(0.0, sx * math.cos(math.radians(self.lid_open_deg))) - WALL_M
            return [rectangle(-sx / 2 + behind, sx / 2, -sy / 2 - 0.004, sy / 2 + 0.004)]
        r = self.radius_m
        if self.lying:  # the body of revolution's axis lies along x
            h = self.height_m or DEFAULT_HEIGHT_M[self.kind]
            return [rectangle(-h / 2, h / 2, -r, r)]
        if self.kind == "cup":
            return [disc(r + 0.002)]
        if self.kind in ("pan", "bowl"):
            segment = r * math.tan(math.pi / RING_SEGMENTS) + 0.001  # the wall's boxes stick out at their corners
            outline = [disc(math.hypot(r + WALL_M / 2, segment))]
            if self.kind == "pan":
                length, width, _ = PAN_HANDLE_M
                outline.append(rectangle(r, r + length, -width / 2, width / 2))
            return outline
        return [disc(r)]


class Randomisation(StrictModel):
    xy_jitter_m: float = Field(default=0.02, ge=0)
    yaw_jitter_deg: float = Field(default=15.0, ge=0)
    min_gap_m: float = Field(default=0.02, ge=0, description="free space kept between footprints")
    max_tries: int = Field(default=200, ge=1)


class ScatterGroup(StrictModel):
    """A seeded number of like objects scattered in a round patch (screws on the table): each becomes a scene
    object named `<name>_<i>` with the fields of `item`; the patch's centre takes the scene's jitter."""

    name: str = Field(pattern=r"^[a-z][a-z0-9_]*$")
    item: SceneObject  # xy_m and yaw_deg are set per member
    count: tuple[int, int] = Field(description="fewest and most members (inclusive)")
    centre_xy_m: tuple[float, float]
    radius_m: float = Field(gt=0, description="patch radius: members' centres lie within it")
    min_gap_m: float = Field(default=0.008, ge=0, description="free table between members' footprints")


class Scene(StrictModel):
    name: str
    description: str = ""
    objects: tuple[SceneObject, ...]
    groups: tuple[ScatterGroup, ...] = ()
    randomise: Randomisation = Randomisation()


def load_scene(path: Path) -> Scene:
    try:
        data = load_yaml(Path(path), "scene")
    except InputFileError as e:
        raise SceneError(str(e)) from None
    try:
        scene = Scene.model_validate(data)
    except ValidationError as e:
        lines = [f"{path}: {'.'.join(str(p) for p in err['loc'])}: {err['msg']}" for err in e.errors()]
        raise SceneError("invalid scene:\n  " + "\n  ".join(lines)) from None
    names = [o.name for o in scene.objects]
    if len(set(names)) != len(names):
        raise SceneError(f"{path}: object names must be unique, got {names}")
    by_name = {o.name: o for o in scene.objects}
    for g in scene.groups:
        lo, hi = g.count
        if not 1 <= lo <= hi <= 50:
            raise SceneError(f"{path}: group {g.name}: count {g.count} must be 1 <= fewest <= most <= 50")
    for o in (*scene.objects, *(g.item.model_copy(update={"name": g.name}) for g in scene.groups)):
        if o.support is not None:
            support = by_name.get(o.support)
            if support is None or not support.is_fixed() or support.top_m() is None or support.support is not None:
                raise SceneError(
                    f"{path}: object {o.name} stands on {o.support!r}: it must be a static object of the scene that "
                    "things stand on (stand, dish_rack, box, platform, plate, dustpan), itself on the table"
                )
        for key in ("color", "lid_color"):
            colour = getattr(o, key)
            if colour is not None and colour not in COLORS:
                raise SceneError(f"{path}: object {o.name}: unknown {key} {colour!r} (known: {', '.join(COLORS)})")
        needs = KIND_NEEDS[o.kind]
        if getattr(o, needs) is None:
            raise SceneError(f"{path}: object {o.name} of kind {o.kind} needs {needs}")
        if o.kind == "screw" and o.height_m is None:
            raise SceneError(f"{path}: object {o.name} of kind screw needs height_m (its length)")
    return scene


def expand_groups(scene: Scene, seed: int) -> Scene:
    """The scene with each group's members as objects: how many and where is drawn from `seed` (members keep
    `min_gap_m` between their footprints, their patch's centre is jittered like an object). SceneError when a
    patch cannot hold its members."""
    if not scene.groups:
        return scene
    rng = np.random.default_rng([seed, 18])
    members = []
    for g in scene.groups:
        n = int(rng.integers(g.count[0], g.count[1] + 1))
        for _ in range(GROUP_ATTEMPTS):
            scattered = _scatter(g, n, scene.randomise, rng)
            if scattered is not None:
                members += scattered
                break
        else:
            raise SceneError(
                f"scene {scene.name}: group {g.name}: no room for {n} members in a patch of radius "
                f"{g.radius_m * 1000:.0f} mm with {g.min_gap_m * 1000:.0f} mm between them ({GROUP_ATTEMPTS} attempts)"
            )
    return scene.model_copy(update={"objects": (*scene.objects, *members), "groups": ()})


def _scatter(g: ScatterGroup, n: int, r: Randomisation, rng: np.random.Generator) -> list[SceneObject] | None:
    """One attempt at placing a group's n members one after the other; None when one finds no room."""
    cx, cy = np.asarray(g.centre_xy_m) + rng.uniform(-r.xy_jitter_m, r.xy_jitter_m, 2)
    placed: list[tuple[SceneObject, list[np.ndarray]]] = []
    for i in range(n):
        for _ in range(r.max_tries):
            radius, bearing = g.radius_m * math.sqrt(rng.uniform()), rng.uniform(0, 2 * math.pi)
            x, y = cx + radius * math.cos(bearing), cy + radius * math.sin(bearing)
            o = g.item.model_copy(
                update={
                    "name": f"{g.name}_{i}",
                    "xy_m": (round(float(x), 4), round(float(y), 4)),
                    "yaw_deg": round(float(rng.uniform(-180.0, 180.0)), 2),
                    "jitter": False,
                    "group": g.name,
                }
            )
            outline = placed_footprint(o, (*o.xy_m, math.radians(o.yaw_deg)))
            if all(footprint_gap(outline, other) >= g.min_gap_m for _, other in placed):
                placed.append((o, outline))
                break
        else:
            return None
    return [o for o, _ in placed]


def place(scene: Scene, seed: int) -> dict[str, tuple[float, float, float]]:
    """Seeded placement: (x, y, yaw) per object, jittered around its nominal pose, footprints kept apart by
    `min_gap_m`. Raises SceneError naming the pair that kept overlapping when no placement is found."""
    rng = np.random.default_rng(seed)
    r = scene.randomise
    clashes: dict[tuple[str, str, float], int] = {}
    for _ in range(r.max_tries):
        poses: dict[str, tuple[float, float, float]] = {}
        for o in scene.objects:
            dx, dy = rng.uniform(-r.xy_jitter_m, r.xy_jitter_m, 2) if o.jitter else (0.0, 0.0)
            dyaw = rng.uniform(-r.yaw_jitter_deg, r.yaw_jitter_deg) if o.jitter else 0.0
            poses[o.name] = (o.xy_m[0] + dx, o.xy_m[1] + dy, math.radians(o.yaw_deg + dyaw))
        for o in scene.objects:  # what stands on a support moves with it
            if o.support is not None:
                poses[o.name] = on_support(o, poses[o.support])
        clash = first_clash(scene.objects, poses, r.min_gap_m)
        if clash is None:
            return poses
        clashes[clash] = clashes.get(clash, 0) + 1
    a, b, gap_m = max(clashes, key=clashes.get)
    raise SceneError(
        f"scene {scene.name}: no placement with seed {seed} keeps the footprints {r.min_gap_m * 1000:.0f} mm apart "
        f"in {r.max_tries} tries: {a} and {b} come within {gap_m * 1000:.0f} mm of each other (by their outlines: "
        "handles, lying bodies and open lids count); move them apart or reduce xy_jitter_m"
    )


def on_support(o: SceneObject, support_pose: tuple[float, float, float]) -> tuple[float, float, float]:
    """The table pose (x, y, yaw) of an object standing on a support at support_pose, from its pose in the
    support's frame (xy_m, yaw_deg)."""
    x, y, yaw = support_pose
    c, s = math.cos(yaw), math.sin(yaw)
    ox, oy = o.xy_m
    return x + c * ox - s * oy, y + s * ox + c * oy, yaw + math.radians(o.yaw_deg)


def placed_footprint(o: SceneObject, pose: tuple[float, float, float]) -> list[np.ndarray]:
    """The object's footprint polygons in the table frame at pose (x, y, yaw)."""
    return [moved(p, *pose) for p in o.footprint()]


def first_clash(
    objects: tuple[SceneObject, ...], poses: dict[str, tuple[float, float, float]], gap_m: float
) -> tuple[str, str, float] | None:
    """The first pair of objects whose footprints come closer than gap_m, with their distance, or None. An object
    and what it stands on, and members of one group (scattered apart already), are not a pair."""
    outlines = {o.name: placed_footprint(o, poses[o.name]) for o in objects}
    for i, a in enumerate(objects):
        for b in objects[i + 1 :]:
            if a.support == b.name or b.support == a.name or (a.group is not None and a.group == b.group):
                continue
            d = footprint_gap(outlines[a.name], outlines[b.name])
            if d < gap_m:
                return a.name, b.name, d
    return None


def _f(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.atleast_1d(values))


def _material(asset: ET.Element, o: SceneObject) -> str:
    rgb = COLORS[o.color]
    name = f"mat_{o.name}"
    if o.texture == "none":
        ET.SubElement(asset, "material", name=name, rgba=_f((*rgb, 1.0)), specular="0.2")
    else:
        dark = tuple(0.6 * c for c in rgb)
        builtin = "checker" if o.texture == "checker" else "gradient"
        ET.SubElement(
            asset,
            "texture",
            name=f"tex_{o.name}",
            type="cube",
            builtin=builtin,
            rgb1=_f(rgb),
            rgb2=_f(dark),
            width="64",
            height="64",
        )
        ET.SubElement(asset, "material", name=name, texture=f"tex_{o.name}", specular="0.2")
    return name


def _geom(body: ET.Element, o: SceneObject, index: int, material: str, **attrs: str) -> None:
    ET.SubElement(
        body,
        "geom",
        {"name": f"{o.name}_g{index}", "material": material, "friction": OBJECT_FRICTION},
        **OBJECT_CONTACT,
        **attrs,
    )


def _ring(
    body: ET.Element,
    o: SceneObject,
    material: str,
    radius: float,
    height: float,
    wall: float,
    z0: float,
    first_index: int,
    n: int = RING_SEGMENTS,
) -> None:
    """A circular wall of n boxes (pan and bowl sides)."""
    seg = 2 * radius * math.tan(math.pi / n) + 0.002
    for k in range(n):
        a = 2 * math.pi * k / n
        _geom(
            body,
            o,
            first_index + k,
            material,
            type="box",
            size=_f((wall / 2, seg / 2, height / 2)),
            pos=_f((radius * math.cos(a), radius * math.sin(a), z0 + height / 2)),
            euler=_f((0, 0, a)),
        )


def add_object(
    worldbody: ET.Element,
    asset: ET.Element,
    o: SceneObject,
    pose: tuple[float, float, float],
    support: SceneObject | None = None,
) -> None:
    """Append one object body (free-floating unless fixed) at pose (x, y, yaw) on the table top (z = 0), or on
    the top of the support it stands on (`support`)."""
    x, y, yaw = pose
    mat = _material(asset, o)
    z = 0.0 if support is None else support.top_m()
    body = ET.SubElement(worldbody, "body", name=o.name, pos=_f((x, y, z)), euler=_f((0, 0, yaw)))
    if not o.is_fixed():
        ET.SubElement(body, "freejoint", name=f"{o.name}_free")
    mass = _f(o.mass_kg)
    if o.kind in TASK_KINDS:
        TASK_KINDS[o.kind](body, asset, o, mat)
    elif o.kind in ("box", "platform"):
        sx, sy, sz = o.size_m
        if o.kind == "platform":  # base and a lighter top plate, like a kitchen scale
            _geom(body, o, 0, mat, type="box", size=_f((sx / 2, sy / 2, sz * 0.4)), pos=_f((0, 0, sz * 0.4)), mass=mass)
            ET.SubElement(asset, "material", name=f"mat_{o.name}_top", rgba="0.85 0.85 0.85 1")
            _geom(
                body,
                o,
                1,
                f"mat_{o.name}_top",
                type="box",
                size=_f((sx * 0.45, sy * 0.45, sz * 0.1)),
                pos=_f((0, 0, sz * 0.9)),
                mass=_f(o.mass_kg * 0.2),
            )
        else:
            _geom(body, o, 0, mat, type="box", size=_f((sx / 2, sy / 2, sz / 2)), pos=_f((0, 0, sz / 2)), mass=mass)
    elif o.kind == "sphere":
        _geom(
            body,
            o,
            0,
            mat,
            type="sphere",
            size=_f(o.radius_m),
            pos=_f((0, 0, o.radius_m)),
            mass=mass,
            condim="6",
            friction=ROLLING_FRICTION,
        )
    elif o.kind in ("cylinder", "plate", "bottle"):
        r = o.radius_m
        h = o.height_m or DEFAULT_HEIGHT_M[o.kind]
        rolls = {"condim": "6", "friction": ROLLING_FRICTION} if o.lying and o.kind != "plate" else {}
        if o.lying:
            pos, euler = (0, 0, r), (0, math.pi / 2, 0)
        else:
            pos, euler = (0, 0, h / 2), (0, 0, 0)
        if o.kind == "bottle":  # body, neck and cap along the bottle axis (local z before tilting)
            inner = ET.SubElement(body, "body", name=f"{o.name}_shape", pos=_f(pos), euler=_f(euler))
            body_h = h * 0.7
            _geom(
                inner,
                o,
                0,
                mat,
                type="cylinder",
                size=_f((r, body_h / 2)),
                pos=_f((0, 0, -h / 2 + body_h / 2)),
                mass=_f(o.mass_kg * 0.85),
                **rolls,
            )
            _geom(
                inner,
                o,
                1,
                mat,
                type="cylinder",
                size=_f((r * 0.45, h * 0.15)),
                pos=_f((0, 0, -h / 2 + body_h + h * 0.15)),
                mass=_f(o.mass_kg * 0.15),
                **rolls,
            )
        else:
            _geom(
                body, o, 0, mat, type="cylinder", size=_f((r, h / 2)), pos=_f(pos), euler=_f(euler), mass=mass, **rolls
            )
    elif o.kind in ("pan", "bowl"):
        r = o.radius_m
        h = o.height_m or DEFAULT_HEIGHT_M[o.kind]
        _geom(body, o, 0, mat, type="cylinder", size=_f((r, WALL_M / 2)), pos=_f((0, 0, WALL_M / 2)), mass=mass)
        _ring(body, o, mat, r, h, WALL_M, WALL_M, first_index=1)
        if o.kind == "pan":
            length, width, thick = PAN_HANDLE_M
            _geom(
                body,
                o,
                30,
                mat,
                type="box",
                size=_f((length / 2, width / 2, thick / 2)),
                pos=_f((r + length / 2, 0, h * 0.8)),
            )
    elif o.kind == "lidded_box":
        sx, sy, sz = o.size_m
        w = WALL_M
        _geom(body, o, 0, mat, type="box", size=_f((sx / 2, sy / 2, w / 2)), pos=_f((0, 0, w / 2)), mass=mass)
        for k, (px, py, hx, hy) in enumerate(
            (
                (sx / 2 - w / 2, 0, w / 2, sy / 2),
                (-sx / 2 + w / 2, 0, w / 2, sy / 2),
                (0, sy / 2 - w / 2, sx / 2, w / 2),
                (0, -sy / 2 + w / 2, sx / 2, w / 2),
            )
        ):
            _geom(body, o, 1 + k, mat, type="box", size=_f((hx, hy, sz / 2)), pos=_f((px, py, sz / 2)))
        # lid hinged along the back (-x) top edge; angle 0 = closed, positive opens upward. The hinge is stiff like
        # a real one (friction 0.02 N m, four times the 50 g lid's weight torque 10 deg past upright): an open lid
        # stays where it was left, one pushed nearly shut falls shut. The friction is a hard constraint (solimp near
        # 1): MuJoCo's default softness let an open lid creep 0.4 deg/s, 10 deg by the time a plan was made
        lid = ET.SubElement(body, "body", name=f"{o.name}_lid", pos=_f((-sx / 2, 0, sz)))
        ET.SubElement(
            lid,
            "joint",
            name=f"{o.name}_hinge",
            type="hinge",
            axis="0 -1 0",
            range="0 1.92",
            damping="0.05",
            frictionloss="0.02",
            solreffriction="0.004 1",
            solimpfriction="0.999 0.9999 0.001",
            ref="0",
        )
        lid_rgb = COLORS[o.lid_color] if o.lid_color else tuple(0.8 * c for c in COLORS[o.color])
        ET.SubElement(asset, "material", name=f"mat_{o.name}_lid", rgba=_f((*lid_rgb, 1)))
        _geom(
            lid,
            o,
            10,
            f"mat_{o.name}_lid",
            type="box",
            size=_f((sx / 2, sy / 2 + 0.004, w / 2)),
            pos=_f((sx / 2, 0, w / 2)),
            mass=_f(0.05),
        )


def _shade(asset: ET.Element, o: SceneObject, name: str, factor: float) -> str:
    """A material of the object's colour scaled by factor (a darker part of it: bristles, a tray)."""
    rgb = tuple(factor * c for c in COLORS[o.color])
    ET.SubElement(asset, "material", name=f"mat_{o.name}_{name}", rgba=_f((*rgb, 1.0)), specular="0.1")
    return f"mat_{o.name}_{name}"


def _box_geom(body: ET.Element, o: SceneObject, index: int, material: str, half: tuple, pos: tuple, **attrs) -> None:
    _geom(body, o, index, material, type="box", size=_f(half), pos=_f(pos), **attrs)


def _add_cup(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """An open cylinder: a bottom and a round wall. The bottom's disc is seen; the cup stands on a square foot
    inside it (box on the table: an analytic contact, where a disc's costs the physics a general convex one)."""
    r, h = o.radius_m, o.height_m or DEFAULT_HEIGHT_M["cup"]
    w = CUP_WALL_M
    visual = {"contype": "0", "conaffinity": "0"}
    ET.SubElement(
        body,
        "geom",
        name=f"{o.name}_g0",
        type="cylinder",
        size=_f((r, w / 2)),
        pos=_f((0, 0, w / 2)),
        material=mat,
        mass=_f(0.3 * o.mass_kg),
        **visual,
    )
    foot = r * math.cos(math.pi / 4) - 0.002
    _box_geom(body, o, 1, mat, (foot, foot, w / 2), (0, 0, w / 2), mass=_f(0.3 * o.mass_kg))
    _ring(body, o, mat, r - w / 2, h - w, w, w, first_index=2, n=CUP_SEGMENTS)


def _add_screw(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """A shank lying along x with a wider head at +x: it rolls in a circle about its head, as screws do. A capsule
    and a ball (analytic contacts: a dozen screws on the table would cost the physics more than the robot as
    cylinders)."""
    r, length = o.radius_m, o.height_m
    head_r = SCREW_HEAD[0] * r
    shank = length - head_r - r  # the capsule's cylinder part: from the shank's round tip to the head's middle
    rolls = {"condim": "6", "friction": SCREW_FRICTION}
    _geom(
        body,
        o,
        0,
        mat,
        type="capsule",
        size=_f((r, shank / 2)),
        pos=_f((-length / 2 + r + shank / 2, 0, head_r)),
        euler=_f((0, math.pi / 2, 0)),
        mass=_f(0.8 * o.mass_kg),
        **rolls,
    )
    _geom(
        body,
        o,
        1,
        mat,
        type="sphere",
        size=_f(head_r),
        pos=_f((length / 2 - head_r, 0, head_r)),
        mass=_f(0.2 * o.mass_kg),
        **rolls,
    )


def _add_brush(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """A head of bristles (a darker shade, sliding easily) under a back, and a handle reaching back (-x) from the
    back's top, its underside BRUSH_HANDLE_LIFT_M above the table. The head carries the mass, so the brush stands
    on its bristles."""
    dx, dy, dz = o.size_m
    length, width, thick = o.handle_m
    bristles = BRISTLE_FRACTION * dz
    _box_geom(
        body,
        o,
        0,
        _shade(asset, o, "bristles", 0.45),
        (dx / 2, dy / 2, bristles / 2),
        (0, 0, bristles / 2),
        mass=_f(0.3 * o.mass_kg),
        friction=BRISTLE_FRICTION,
    )
    _box_geom(
        body, o, 1, mat, (dx / 2, dy / 2, (dz - bristles) / 2), (0, 0, (dz + bristles) / 2), mass=_f(0.55 * o.mass_kg)
    )
    lift = BRUSH_HANDLE_LIFT_M
    _box_geom(
        body,
        o,
        2,
        mat,
        (length / 2, width / 2, thick / 2),
        (-dx / 2 - length / 2, 0, lift + thick / 2),
        mass=_f(0.15 * o.mass_kg),
    )


def _add_dustpan(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """A floor, a ramp from the table up to it along the open +x side, walls on the other three sides."""
    dx, dy, wall_h = o.size_m
    f, lip, w = DUSTPAN_FLOOR_M, DUSTPAN_LIP_M, DUSTPAN_WALL_M
    floor_x = (-dx / 2, dx / 2 - lip)
    _box_geom(body, o, 0, mat, ((floor_x[1] - floor_x[0]) / 2, dy / 2, f / 2), (sum(floor_x) / 2, 0, f / 2))
    slope = math.atan2(f, lip)
    half_len = math.hypot(lip, f) / 2
    _geom(  # the ramp: its top face runs from the table at the front edge to the floor's top
        body,
        o,
        1,
        mat,
        type="box",
        size=_f((half_len, dy / 2, f / 2)),
        pos=_f((dx / 2 - lip / 2 + 0.5 * f * math.sin(slope), 0, f / 2 - 0.5 * f * math.cos(slope))),
        euler=_f((0, slope, 0)),
    )
    _box_geom(body, o, 2, mat, (w / 2, dy / 2, wall_h / 2), (-dx / 2 + w / 2, 0, wall_h / 2))
    for k, side in enumerate((-1, 1)):
        _box_geom(
            body, o, 3 + k, mat, ((dx - lip) / 2, w / 2, wall_h / 2), (-lip / 2, side * (dy / 2 - w / 2), wall_h / 2)
        )


def _add_dish_rack(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """A tray and two rows of tines along x, one each side of y = 0: a plate standing on its rim (lying: true,
    its face towards x) rests midway between two tines of each row."""
    dx, dy, tine_h = o.size_m
    b, t = RACK_BASE_M, RACK_TINE_M
    _box_geom(body, o, 0, _shade(asset, o, "tray", 0.8), (dx / 2, dy / 2, b / 2), (0, 0, b / 2))
    pitch = RACK_PITCH_M
    slots = int(dx // pitch)
    index = 1
    for row in (-0.3 * dy, 0.3 * dy):
        for x in (np.arange(slots + 1) - slots / 2) * pitch:
            _box_geom(body, o, index, mat, (t / 2, t / 2, tine_h / 2), (x, row, b + tine_h / 2))
            index += 1


def _add_stand(body: ET.Element, asset: ET.Element, o: SceneObject, mat: str) -> None:
    """A board on four legs at its corners."""
    sx, sy, h = o.size_m
    board, leg = STAND_BOARD_M, STAND_LEG_M
    _box_geom(body, o, 0, mat, (sx / 2, sy / 2, board / 2), (0, 0, h - board / 2))
    for k, (px, py) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        pos = (px * (sx / 2 - leg / 2), py * (sy / 2 - leg / 2), (h - board) / 2)
        _box_geom(body, o, 1 + k, mat, (leg / 2, leg / 2, (h - board) / 2), pos)


TASK_KINDS = {
    "cup": _add_cup,
    "screw": _add_screw,
    "brush": _add_brush,
    "dustpan": _add_dustpan,
    "dish_rack": _add_dish_rack,
    "stand": _add_stand,
}
