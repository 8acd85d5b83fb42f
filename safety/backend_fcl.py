"""Collision backend on python-fcl, answering exactly the questions of CoalBackend (same Scene), kept to measure
the two side by side (bench/safety.py) and as a cross-check in the tests.

python-fcl has no point-cloud octree constructor (fcl.OcTree takes serialised octomap bytes only), so each cloud
chunk becomes one fcl.Box per occupied cell of the same coal octree the coal backend uses. Its broad-phase managers
call back into Python for every candidate pair, so the broad phase for primitive pairs is a vectorised
AABB test in numpy and only the overlapping pairs reach fcl.collide; each robot primitive near the cloud is
tested against a DynamicAABBTree manager of the cells.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import fcl
import numpy as np
import pinocchio as pin

from safety.backend_coal import add_primitive, octree
from safety.geometry import WORLD, Primitive

if TYPE_CHECKING:
    from safety.robot_model import RobotModel
    from safety.scene import Scene


def to_fcl(prim: Primitive) -> fcl.CollisionGeometry:
    s = prim.size
    if prim.kind == "box":
        return fcl.Box(*s)
    if prim.kind == "cylinder":
        return fcl.Cylinder(s[0], s[1])
    if prim.kind == "capsule":
        return fcl.Capsule(s[0], s[1])
    return fcl.Sphere(s[0])


def _aabb_half_extent(prim: Primitive) -> np.ndarray:
    """Half extents of the base-axis box around a fixed world primitive (exact for boxes, sphere bound otherwise).
    Moving primitives use their bounding radius instead, valid in any orientation."""
    if prim.kind == "box":
        return np.abs(prim.T_link_geom[:3, :3]) @ (np.asarray(prim.size) / 2)
    return np.full(3, prim.bounding_radius())


class _FirstHit:
    """Collision callback data: stop the manager's traversal at the first touching cell."""

    def __init__(self) -> None:
        self.request, self.result, self.done = fcl.CollisionRequest(), fcl.CollisionResult(), False


class FclBackend:
    name = "fcl"

    def __init__(self, robot: RobotModel, scene: Scene) -> None:
        self.model, self.data = robot.model, robot.model.createData()
        self.movers = [k for k, o in enumerate(scene.objects) if o.role in ("robot", "held")]
        self.gmodel = pin.GeometryModel()  # placements of the moving shapes, computed by Pinocchio
        for k in self.movers:
            add_primitive(self.gmodel, robot, scene.objects[k].prim)
        self.gdata = self.gmodel.createData()
        n = len(scene.objects)
        self.objects: list[fcl.CollisionObject | None] = [None] * n
        self.center, self.half = np.zeros((n, 3)), np.zeros((n, 3))
        self.clouds: dict[int, fcl.DynamicAABBTreeCollisionManager] = {}
        for k, obj in enumerate(scene.objects):
            if obj.prim is None:
                self._build_cloud(k, obj.points, scene.cloud_resolution_m)
                continue
            self.objects[k] = fcl.CollisionObject(to_fcl(obj.prim), fcl.Transform())
            self.half[k] = _aabb_half_extent(obj.prim) if obj.prim.link == WORLD else obj.prim.bounding_radius()
            if obj.prim.link == WORLD:
                T = obj.prim.T_link_geom
                self.objects[k].setTransform(fcl.Transform(T[:3, :3], T[:3, 3]))
                self.center[k] = T[:3, 3]
        self.pairs = scene.pairs
        # primitive pairs first, cloud pairs last: a hit on a primitive is found without touching the cloud
        order = sorted(range(len(scene.pairs)), key=lambda i: scene.pairs[i][1] in self.clouds)
        self.pair_ids = np.array(order, dtype=int)
        self.pa = np.array([scene.pairs[i][0] for i in order], dtype=int)
        self.pb = np.array([scene.pairs[i][1] for i in order], dtype=int)
        self.request = fcl.CollisionRequest()

    def _build_cloud(self, k: int, points: np.ndarray, resolution_m: float) -> None:
        cells = np.array([list(b)[:4] for b in octree(points, resolution_m).toBoxes()])
        manager = fcl.DynamicAABBTreeCollisionManager()
        manager.registerObjects([fcl.CollisionObject(fcl.Box(s, s, s), fcl.Transform(np.eye(3), c)) for *c, s in cells])
        manager.setup()
        lo, hi = cells[:, :3] - cells[:, 3:] / 2, cells[:, :3] + cells[:, 3:] / 2
        self.clouds[k], self.center[k], self.half[k] = manager, (lo.min(0) + hi.max(0)) / 2, (hi.max(0) - lo.min(0)) / 2

    def _place(self, q_full: np.ndarray) -> None:
        pin.updateGeometryPlacements(self.model, self.data, self.gmodel, self.gdata, q_full)
        for g, k in enumerate(self.movers):
            M = self.gdata.oMg[g]
            self.objects[k].setTransform(fcl.Transform(M.rotation, M.translation))
            self.center[k] = M.translation

    def _candidates(self) -> np.ndarray:
        gap = np.abs(self.center[self.pa] - self.center[self.pb]) <= self.half[self.pa] + self.half[self.pb]
        return np.flatnonzero(np.all(gap, axis=1))

    def _touch(self, a: int, b: int) -> bool:
        cloud = self.clouds.get(b)
        if cloud is None:
            return fcl.collide(self.objects[a], self.objects[b], self.request, fcl.CollisionResult()) > 0
        data = _FirstHit()
        cloud.collide(self.objects[a], data, fcl.defaultCollisionCallback)
        return data.result.is_collision

    def _hits(self, stop_at_first: bool) -> list[int]:
        hits = []
        for c in self._candidates():
            if self._touch(self.pa[c], self.pb[c]):
                hits.append(int(self.pair_ids[c]))
                if stop_at_first:
                    break
        return sorted(hits)

    def in_collision(self, q_full: np.ndarray) -> bool:
        self._place(q_full)
        return bool(self._hits(stop_at_first=True))

    def colliding_pairs(self, q_full: np.ndarray) -> list[int]:
        self._place(q_full)
        return self._hits(stop_at_first=False)
