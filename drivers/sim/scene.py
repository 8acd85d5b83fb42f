"""Scene files (configs/scenes/*.yaml): the objects on the table, validated, placed by seed, written as MJCF.

Object kinds: box, cylinder, sphere, plate, bottle (optionally lying on its side), pan, bowl, platform (a small
scale), lidded_box (a box whose lid is hinged at the back). Static objects are welded to the table.
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
DEFAULT_HEIGHT_M = {"cylinder": 0.1, "plate": 0.015, "bottle": 0.22, "pan": 0.04, "bowl": 0.07}


class SceneError(ValueError):
    pass


class SceneObject(StrictModel):
    name: str = Field(pattern=r"^[a-z][a-z0-9_]*$")
    kind: Literal["box", "cylinder", "sphere", "plate", "bottle", "pan", "bowl", "platform", "lidded_box"]
    color: str = "red"
    texture: Literal["none", "checker", "stripes"] = "none"
    size_m: tuple[float, float, float] | None = Field(default=None, description="box, platform, lidded_box")
    radius_m: float | None = Field(default=None, gt=0, description="cylinder, sphere, plate, bottle, pan, bowl")
    height_m: float | None = Field(default=None, gt=0, description="cylinder, bottle, pan, bowl, plate")
    mass_kg: float = Field(default=0.15, gt=0)
    xy_m: tuple[float, float]
    yaw_deg: float = 0.0
    lying: bool = Field(default=False, description="bottle/cylinder on its side")
    lid_open_deg: float = Field(default=100.0, ge=0, le=110, description="lidded_box initial lid angle")
    lid_color: str | None = Field(default=None, description="lidded_box lid colour; default a darker body colour")
    fixed: bool | None = Field(default=None, description="welded to the table; default per kind")
    jitter: bool = Field(default=True, description="apply the scene's placement randomisation")

    def is_fixed(self) -> bool:
        if self.fixed is not None:
            return self.fixed
        return self.kind in ("pan", "bowl", "platform", "lidded_box")

    def footprint(self) -> list[np.ndarray]:
        """The table area the object covers, as convex polygons [m] in its own frame (x, y before the yaw)."""
        if self.kind in ("box", "platform"):
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


class Scene(StrictModel):
    name: str
    description: str = ""
    objects: tuple[SceneObject, ...]
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
    for o in scene.objects:
        for key in ("color", "lid_color"):
            colour = getattr(o, key)
            if colour is not None and colour not in COLORS:
                raise SceneError(f"{path}: object {o.name}: unknown {key} {colour!r} (known: {', '.join(COLORS)})")
        needs = {
            "box": "size_m",
            "platform": "size_m",
            "lidded_box": "size_m",
            "cylinder": "radius_m",
            "sphere": "radius_m",
            "plate": "radius_m",
            "bottle": "radius_m",
            "pan": "radius_m",
            "bowl": "radius_m",
        }[o.kind]
        if getattr(o, needs) is None:
            raise SceneError(f"{path}: object {o.name} of kind {o.kind} needs {needs}")
    return scene


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


def placed_footprint(o: SceneObject, pose: tuple[float, float, float]) -> list[np.ndarray]:
    """The object's footprint polygons in the table frame at pose (x, y, yaw)."""
    return [moved(p, *pose) for p in o.footprint()]


def first_clash(
    objects: tuple[SceneObject, ...], poses: dict[str, tuple[float, float, float]], gap_m: float
) -> tuple[str, str, float] | None:
    """The first pair of objects whose footprints come closer than gap_m, with their distance, or None."""
    outlines = {o.name: placed_footprint(o, poses[o.name]) for o in objects}
    for i, a in enumerate(objects):
        for b in objects[i + 1 :]:
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


def add_object(worldbody: ET.Element, asset: ET.Element, o: SceneObject, pose: tuple[float, float, float]) -> None:
    """Append one object body (free-floating unless fixed) at pose (x, y, yaw) on the table top (z = 0)."""
    x, y, yaw = pose
    mat = _material(asset, o)
    body = ET.SubElement(worldbody, "body", name=o.name, pos=_f((x, y, 0.0)), euler=_f((0, 0, yaw)))
    if not o.is_fixed():
        ET.SubElement(body, "freejoint", name=f"{o.name}_free")
    mass = _f(o.mass_kg)
    if o.kind in ("box", "platform"):
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
        rolls = {"condim": "6", "friction": ROLLING_FRICTION} if o.lying else {}
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
