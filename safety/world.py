"""The scene around the robot as data: obstacles from a world description (WORLD.json), the table, the
workspace walls and keep-out boxes from the safety config, and a held object attached to the TCP.

WORLD.json (base frame, metres/radians; unknown keys are errors):
    {"boxes": [{"name": "bin", "center": [x, y, z], "size": [sx, sy, sz], "rpy": [r, p, y]}],
     "spheres": [{"center": [...], "radius": r}],
     "cylinders": [{"center": [...], "radius": r, "length": l, "rpy": [...]}],   # axis = local z
     "points_file": "cloud.npz",        # optional, npz with `points` (N, 3), base frame; relative to WORLD.json
     "held_object": {"kind": "box", "size": [...], "xyz": [...], "rpy": [...]},  # optional, in the TCP frame
     "gripper_width_m": 0.05}           # optional finger gap; default: open
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from safety.config import BoxRegion, SafetyConfig
from safety.geometry import WORLD, Primitive, pose, pose_rpy

Vec3 = tuple[float, float, float]
Positive = Annotated[float, Field(gt=0)]

TABLE_THICKNESS_M = 0.1
TABLE_HALF_EXTENT_M = 2.0  # the table is modelled as a 4 m x 4 m slab: bigger than any reach
WALL_THICKNESS_M = 2.0


class _Input(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class BoxIn(_Input):
    name: str = ""
    center: Vec3
    size: tuple[Positive, Positive, Positive]
    rpy: Vec3 = (0.0, 0.0, 0.0)


class SphereIn(_Input):
    name: str = ""
    center: Vec3
    radius: Positive


class CylinderIn(_Input):
    name: str = ""
    center: Vec3
    radius: Positive
    length: Positive
    rpy: Vec3 = (0.0, 0.0, 0.0)


class HeldObjectIn(_Input):
    """Geometry of the object in the gripper, posed in the TCP frame."""

    name: str = "held"
    kind: Literal["box", "cylinder", "sphere"]
    size: tuple[Positive, ...] = Field(description="box (sx, sy, sz); cylinder (radius, length); sphere (radius,)")
    xyz: Vec3 = (0.0, 0.0, 0.0)
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
    boxes: tuple[BoxIn, ...] = ()
    spheres: tuple[SphereIn, ...] = ()
    cylinders: tuple[CylinderIn, ...] = ()
    points_file: str | None = None
    held_object: HeldObjectIn | None = None
    gripper_width_m: Annotated[float, Field(ge=0)] | None = None

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


class WorldFileError(ValueError):
    """WORLD.json or its points file is unusable; the message names the file and the problem."""


def load_world_file(path: Path) -> tuple[WorldDescription, np.ndarray | None]:
    """Read and validate WORLD.json and its optional point cloud (base frame, (N, 3) finite)."""
    try:
        desc = WorldDescription.model_validate(json.loads(Path(path).read_text()))
    except (OSError, json.JSONDecodeError) as e:
        raise WorldFileError(f"{path}: cannot read world JSON: {e}") from e
    except ValidationError as e:
        raise WorldFileError(f"{path}: invalid world description: {_first_errors(e)}") from e
    if desc.points_file is None:
        return desc, None
    cloud_path = (Path(path).parent / desc.points_file).resolve()
    try:
        with np.load(cloud_path) as npz:
            points = np.asarray(npz["points"], dtype=np.float64)
    except (OSError, KeyError, ValueError) as e:
        raise WorldFileError(f"{path}: points_file {cloud_path}: cannot read array 'points': {e}") from e
    if points.ndim != 2 or points.shape[1] != 3:
        raise WorldFileError(f"{cloud_path}: points must be (N, 3), got {points.shape}")
    if not np.all(np.isfinite(points)):
        raise WorldFileError(f"{cloud_path}: points contain NaN or inf")
    return desc, points


def _first_errors(e: ValidationError, limit: int = 3) -> str:
    parts = [f"{'.'.join(str(x) for x in err['loc']) or '<root>'}: {err['msg']}" for err in e.errors()[:limit]]
    return "; ".join(parts)


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
