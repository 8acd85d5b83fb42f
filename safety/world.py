"""The scene around the robot as data: obstacles from a world description (WORLD.json), the table, the
workspace walls and keep-out boxes from the safety config, and a held object attached to the TCP.

WORLD.json (base frame, metres/radians; unknown keys are errors):
    {"boxes": [{"name": "bin", "center": [x, y, z], "size": [sx, sy, sz], "rpy": [r, p, y]}],
     "spheres": [{"center": [...], "radius": r}],
     "cylinders": [{"center": [...], "radius": r, "length": l, "rpy": [...]}],   # axis = local z
     "points_file": "cloud.npz",        # optional, npz with `points` (N, 3), base frame; relative to WORLD.json
     "held_object": {"kind": "box", "size": [...], "xyz": [...], "rpy": [...]},  # optional, in the TCP frame
     "gripper_width_m": 0.05}           # optional finger gap; default: open
Every number is finite and physical: positions within the cell (drivers.config.CELL_EXTENT_M), sizes positive and
at most 20 m, at most 1000 shapes of a kind. The points file is an .npz with the one array `points`, numeric,
(N, 3) with N <= MAX_POINTS, finite and within the cell; its declared size is checked before it is loaded.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from drivers.config import CELL_EXTENT_M, Position
from drivers.files import InputFileError, load_json, read_npz
from safety.config import BoxRegion, SafetyConfig
from safety.geometry import WORLD, Primitive, pose, pose_rpy

Vec3 = tuple[float, float, float]
Positive = Annotated[float, Field(gt=0, le=20.0)]  # [m] a shape's size
Near = Annotated[float, Field(ge=-2.0, le=2.0)]  # [m] an offset from the TCP
MAX_SHAPES = 1000  # of each kind
MAX_POINTS = 2_000_000  # a Femto Bolt frame has 1 M at most
MAX_POINTS_FILE_BYTES = 256 * 2**20

TABLE_THICKNESS_M = 0.1
TABLE_HALF_EXTENT_M = 2.0  # the table is modelled as a 4 m x 4 m slab: bigger than any reach
WALL_THICKNESS_M = 2.0


class _Input(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


Name = Annotated[str, Field(max_length=200)]


class BoxIn(_Input):
    name: Name = ""
    center: Position
    size: tuple[Positive, Positive, Positive]
    rpy: Vec3 = (0.0, 0.0, 0.0)


class SphereIn(_Input):
    name: Name = ""
    center: Position
    radius: Positive


class CylinderIn(_Input):
    name: Name = ""
    center: Position
    radius: Positive
    length: Positive
    rpy: Vec3 = (0.0, 0.0, 0.0)


class HeldObjectIn(_Input):
    """Geometry of the object in the gripper, posed in the TCP frame."""

    name: Name = "held"
    kind: Literal["box", "cylinder", "sphere"]
    size: tuple[Annotated[float, Field(gt=0, le=2.0)], ...] = Field(
        max_length=3, description="box (sx, sy, sz); cylinder (radius, length); sphere (radius,)"
    )
    xyz: tuple[Near, Near, Near] = (0.0, 0.0, 0.0)
    rpy: Vec3 = (0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _size(self) -> HeldObjectIn:
        need = {"box": 3, "cylinder": 2, "sphere": 1}[self.kind]
        if len(self.size) != need:
            raise ValueError(f"held_object of kind {self.kind} needs {need} size values, got {len(self.size)}")
        return self

    def primitive(self, tcp_link: str) -> Primitive:
        return Primitive(f"held:{self.name}", tcp_link, self.kind, tuple(self.size), pose_rpy(self.xyz, self.rpy))


class WorldDescription(_Input):
    boxes: tuple[BoxIn, ...] = Field(default=(), max_length=MAX_SHAPES)
    spheres: tuple[SphereIn, ...] = Field(default=(), max_length=MAX_SHAPES)
    cylinders: tuple[CylinderIn, ...] = Field(default=(), max_length=MAX_SHAPES)
    points_file: Annotated[str, Field(min_length=1, max_length=4096)] | None = None
    held_object: HeldObjectIn | None = None
    gripper_width_m: Annotated[float, Field(ge=0, le=1.0)] | None = None

    def obstacles(self) -> list[Primitive]:
        out = [
            Primitive(b.name or f"box{i}", WORLD, "box", b.size, pose_rpy(b.center, b.rpy))
            for i, b in enumerate(self.boxes)
        ]
        out += [
            Primitive(s.name or f"sphere{i}", WORLD, "sphere", (s.radius,), pose(s.center))
            for i, s in enumerate(self.spheres)
        ]
        out += [
            Primitive(c.name or f"cylinder{i}", WORLD, "cylinder", (c.radius, c.length), pose_rpy(c.center, c.rpy))
            for i, c in enumerate(self.cylinders)
        ]
        return out


class WorldFileError(InputFileError):
    """WORLD.json or its points file is unusable; it names the file, the key and the problem."""


def load_world_file(path: Path) -> tuple[WorldDescription, np.ndarray | None]:
    """Read and validate WORLD.json and its optional point cloud (base frame, (N, 3) finite)."""
    try:
        data = load_json(path, "world JSON", max_values=100_000)
    except InputFileError as e:
        raise WorldFileError(e.file, e.problem, e.key, e.line, e.column) from None
    try:
        desc = WorldDescription.model_validate(data)
    except ValidationError as e:
        errors = e.errors(include_url=False)
        keys = [".".join(str(x) for x in err["loc"]) or "<root>" for err in errors]
        problems = "; ".join(f"{k}: {err['msg']}" for k, err in zip(keys[:3], errors, strict=False))
        raise WorldFileError(path, f"invalid world description: {problems}", keys[0]) from None
    if desc.points_file is None:
        return desc, None
    try:
        cloud_path = (Path(path).parent / desc.points_file).resolve()
    except (OSError, ValueError, RuntimeError) as e:
        raise WorldFileError(path, f"not a usable path ({e})", "points_file") from None
    try:
        return desc, load_points_file(cloud_path)
    except InputFileError as e:  # named from WORLD.json, whose points_file it is
        where = f"{e.key}: " if e.key else ""
        raise WorldFileError(path, f"{cloud_path}: {where}{e.problem}", "points_file") from None


def _points_header(key: str, shape: tuple[int, ...], dtype: np.dtype) -> None:
    if key != "points":
        raise ValueError("unknown key (a points file holds only `points`)")
    if dtype.kind not in "fiu" or len(shape) != 2 or shape[1] != 3 or shape[0] > MAX_POINTS:
        raise ValueError(f"must be numeric (N, 3) with N <= {MAX_POINTS:,}, got {dtype} {shape}")


def load_points_file(path: Path) -> np.ndarray:
    """`points` (N, 3) [m, base frame] of an .npz, as float64, finite and within the cell; InputFileError if not."""
    arrays = read_npz(path, "points file", MAX_POINTS_FILE_BYTES, MAX_POINTS * 3 * 8, _points_header)
    if "points" not in arrays:
        raise InputFileError(path, "missing (an .npz with the array `points`, N x 3)", "points")
    points = arrays["points"].astype(np.float64)
    if not np.all(np.isfinite(points)):
        raise InputFileError(path, "contains NaN or inf", "points")
    far = float(np.abs(points).max(initial=0.0))
    if far > CELL_EXTENT_M:
        raise InputFileError(path, f"a coordinate of {far:.4g} m lies outside the cell (+-{CELL_EXTENT_M} m)", "points")
    return points


def table_primitive() -> Primitive:
    """The table as a slab whose top face is z = 0 of the base frame."""
    size = (2 * TABLE_HALF_EXTENT_M, 2 * TABLE_HALF_EXTENT_M, TABLE_THICKNESS_M)
    return Primitive("table", WORLD, "box", size, pose((0.0, 0.0, -TABLE_THICKNESS_M / 2)))


def workspace_walls(box: BoxRegion) -> list[Primitive]:
    """Six slabs enclosing the workspace box from outside: a shape touching one has left the workspace."""
    lo, hi = np.asarray(box.min_m), np.asarray(box.max_m)
    center, extent = (lo + hi) / 2, hi - lo
    walls = []
    for axis, label in enumerate("xyz"):
        for sign, end in ((-1, lo), (1, hi)):
            size = extent + 2 * WALL_THICKNESS_M
            size[axis] = WALL_THICKNESS_M
            c = center.copy()
            c[axis] = end[axis] + sign * WALL_THICKNESS_M / 2
            walls.append(Primitive(f"workspace:{'-+'[sign > 0]}{label}", WORLD, "box", tuple(size), pose(c)))
    return walls


def keep_out_boxes(config: SafetyConfig) -> list[Primitive]:
    out = []
    for i, box in enumerate(config.keep_out):
        lo, hi = np.asarray(box.min_m), np.asarray(box.max_m)
        out.append(Primitive(f"keep_out:{box.name or i}", WORLD, "box", tuple(hi - lo), pose((lo + hi) / 2)))
    return out
