"""Collision backend on coal (FCL's maintained fork) through Pinocchio's GeometryModel: forward kinematics,
geometry placement and the pair loop all run in C++ in one call. The broad phase is coal's naive manager (an
all-pairs AABB test): with ~35 objects it beats the dynamic AABB tree, 11 vs 25 us per check measured.

This is the runtime backend: on the same checks it is several times faster than python-fcl, whose broad phase
calls back into Python for every candidate pair (figures in bench/safety.py and the README).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import coal
import numpy as np
import pinocchio as pin

from safety.geometry import WORLD, Primitive

if TYPE_CHECKING:
    from safety.robot_model import RobotModel
    from safety.scene import Scene


def to_coal(prim: Primitive) -> coal.CollisionGeometry:
    s = prim.size
    if prim.kind == "box":
        return coal.Box(*s)
    if prim.kind == "cylinder":
        return coal.Cylinder(s[0], s[1])
    if prim.kind == "capsule":
        return coal.Capsule(s[0], s[1])
    return coal.Sphere(s[0])


def add_primitive(gmodel: pin.GeometryModel, robot: RobotModel, prim: Primitive) -> int:
    """Attach a primitive to its frame (or the universe for WORLD) in a GeometryModel; returns its index."""
    if prim.link == WORLD:
        joint, frame, placement = 0, 0, pin.SE3(prim.T_link_geom)
    else:
        frame = robot.model.getFrameId(prim.link)
        f = robot.model.frames[frame]
        joint, placement = f.parentJoint, f.placement * pin.SE3(prim.T_link_geom)
    return gmodel.addGeometryObject(pin.GeometryObject(prim.name, joint, frame, placement, to_coal(prim)))


def octree(points: np.ndarray, resolution_m: float) -> coal.OcTree:
    return coal.makeOctree(np.ascontiguousarray(points, dtype=np.float64), resolution_m)


class CoalBackend:
    """Collision queries for one Scene. Not thread-safe (one pin.Data); build one per thread."""

    name = "coal"

    def __init__(self, robot: RobotModel, scene: Scene) -> None:
        self.model = robot.model
        self.data = robot.model.createData()
        self.gmodel = pin.GeometryModel()
        for obj in scene.objects:
            if obj.prim is not None:
                add_primitive(self.gmodel, robot, obj.prim)
            else:
                tree = octree(obj.points, scene.cloud_resolution_m)
                self.gmodel.addGeometryObject(pin.GeometryObject(obj.name, 0, 0, pin.SE3.Identity(), tree))
        for a, b, _ in scene.pairs:
            self.gmodel.addCollisionPair(pin.CollisionPair(a, b))
        self.gdata = self.gmodel.createData()
        self.broadphase = pin.BroadPhaseManager_NaiveCollisionManager(self.model, self.gmodel, self.gdata)

    def in_collision(self, q_full: np.ndarray) -> bool:
        """FK + broad phase + narrow phase, stopping at the first colliding pair."""
        return bool(pin.computeCollisions(self.model, self.data, self.broadphase, q_full, True))

    def colliding_pairs(self, q_full: np.ndarray) -> list[int]:
        """Indices (into scene.pairs) of every colliding pair."""
        pin.computeCollisions(self.model, self.data, self.gmodel, self.gdata, q_full, False)
        return [k for k, r in enumerate(self.gdata.collisionResults) if r.isCollision()]
