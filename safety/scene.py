"""What is checked against what: the list of collision objects (robot primitives padded, held object, table,
workspace walls, keep-out boxes, obstacles, point cloud) and the pairs to test, each tagged with the violation
kind it reports. Both backends are built from one Scene, so they answer exactly the same question.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from safety.config import SafetyConfig
from safety.geometry import Primitive, robot_primitives
from safety.robot_model import RobotModel
from safety.self_collision import checked_self_pairs
from safety.world import keep_out_boxes, table_primitive, workspace_walls

Role = Literal["robot", "held", "table", "workspace", "keep_out", "obstacle", "cloud"]
CollisionKind = Literal["self_collision", "collision", "workspace", "keep_out"]
CLOUD_NAME = "point_cloud"
CLOUD_CHUNK_M = 0.3  # the cloud is split on this grid so each octree's box is tight and the broad phase prunes
_KIND_OF_ROLE: dict[str, CollisionKind] = {
    "robot": "self_collision",
    "held": "self_collision",
    "table": "collision",
    "obstacle": "collision",
    "cloud": "collision",
    "workspace": "workspace",
    "keep_out": "keep_out",
}


@dataclass(frozen=True)
class SceneObject:
    name: str
    role: Role
    prim: Primitive | None  # None for a point-cloud chunk
    link: str = ""  # robot link for robot/held objects, "" for the world
    points: np.ndarray | None = None  # the chunk's points (base frame) when prim is None


@dataclass(frozen=True)
class Scene:
    objects: tuple[SceneObject, ...]
    pairs: tuple[tuple[int, int, CollisionKind], ...]  # (object, object, violation kind)
    cloud_resolution_m: float


def build_scene(
    robot: RobotModel,
    config: SafetyConfig,
    obstacles: list[Primitive] = (),
    points: np.ndarray | None = None,
    held: Primitive | None = None,
    table: bool = True,
    held_padding_m: float | None = None,
) -> Scene:
    """Robot primitives (padded by config.padding_m) and the held object (padded by held_padding_m, default the
    same) against everything else; the base, bolted to the table, is not tested against the table or the
    workspace floor; the held object is not tested against the gripper that holds it."""
    pad = config.padding_m
    robot_prims = [p.padded(pad) for p in robot_primitives(robot.spec)]
    objects = [SceneObject(p.name, "robot", p, p.link) for p in robot_prims]
    if held is not None:
        held_pad = pad if held_padding_m is None else held_padding_m
        objects.append(SceneObject(held.name, "held", held.padded(held_pad), held.link))
    world: list[SceneObject] = []
    if table:
        world.append(SceneObject("table", "table", table_primitive()))
    world += [SceneObject(p.name, "workspace", p) for p in workspace_walls(config.workspace)]
    world += [SceneObject(p.name, "keep_out", p) for p in keep_out_boxes(config)]
    world += [SceneObject(p.name, "obstacle", p) for p in obstacles]
    if points is not None and len(points):
        world += [SceneObject(CLOUD_NAME, "cloud", None, points=chunk) for chunk in split_cloud(points, CLOUD_CHUNK_M)]
    objects += world

    pairs: list[tuple[int, int, CollisionKind]] = [
        (i, j, "self_collision") for i, j in checked_self_pairs(robot, robot_prims, pad)
    ]
    movers = [k for k, o in enumerate(objects) if o.role in ("robot", "held")]
    base = robot.spec.base_link
    for k in movers:
        for w, obj in enumerate(objects):
            if obj.role in ("robot", "held"):
                continue
            if objects[k].link == base and obj.role in ("table", "workspace"):
                continue
            pairs.append((k, w, _KIND_OF_ROLE[obj.role]))
    if held is not None:
        h = len(robot_prims)
        pairs += [
            (k, h, "self_collision") for k in range(len(robot_prims)) if not _holds(robot, objects[k].link, held.link)
        ]
    return Scene(tuple(objects), tuple(pairs), config.cloud_voxel_m)


def split_cloud(points: np.ndarray, chunk_m: float) -> list[np.ndarray]:
    """The points grouped by the chunk_m grid cell they fall in. One octree over a whole scene has a bounding box
    that every link overlaps, so every check would traverse it (measured 36 vs 13 us per check)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    _, cell = np.unique(np.floor(points / chunk_m).astype(np.int64), axis=0, return_inverse=True)
    cell = cell.reshape(-1)
    order = np.argsort(cell, kind="stable")
    bounds = np.flatnonzero(np.diff(cell[order])) + 1
    return np.split(points[order], bounds)


def _holds(robot: RobotModel, link: str, tcp_link: str) -> bool:
    """Whether a robot link is part of the hand holding the object (the flange body or a finger on it)."""
    frames, parents = robot.model.frames, robot.model.parents
    hand = frames[robot.model.getFrameId(tcp_link)].parentJoint
    body = frames[robot.model.getFrameId(link)].parentJoint
    return body == hand or parents[body] == hand
