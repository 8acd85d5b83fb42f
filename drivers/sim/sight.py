"""What a camera fixed in the world sees of a scene's objects, before anything is simulated: a generated task names
only objects the camera shows (a block behind an open chest's lid is no object a person would point at there).

Each object is a stack of prisms (its footprint polygons between two heights, an open lid a slab above its box's
back edge); an object's share in sight is the share of points over its top whose line to the camera crosses no
other object's prism. Footprints cover their object (a disc's polygon is circumscribed), so the share errs low.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.sim.footprint import moved, rectangle
from drivers.sim.scene import DEFAULT_HEIGHT_M, WALL_M, Scene, SceneObject, placed_footprint

GRID = 7  # points per side of the grid laid over an object's footprint
Prism = tuple[np.ndarray, float, float]  # a convex polygon (counterclockwise, table frame) between two heights [m]


def height_m(o: SceneObject) -> float:
    """The height of the object's top above the table [m] (a box's without its lid)."""
    if o.size_m is not None:
        return o.size_m[2]
    if o.kind == "sphere" or o.lying:
        return 2 * o.radius_m
    return o.height_m or DEFAULT_HEIGHT_M[o.kind]


def prisms(o: SceneObject) -> list[Prism]:
    """The object as prisms in the table frame: its footprint up to its top, and an open lid over its back edge."""
    pose = (*o.xy_m, math.radians(o.yaw_deg))
    top = height_m(o)
    out = [(polygon, 0.0, top) for polygon in placed_footprint(o, pose)]
    if o.kind == "lidded_box":
        sx, sy, _ = o.size_m
        angle = math.radians(o.lid_open_deg)
        reach = sx * math.cos(angle)  # the lid's tip from the hinge along x; the hinge on the back (-x) top edge
        lid = rectangle(-sx / 2 + min(0.0, reach) - WALL_M, -sx / 2 + max(0.0, reach) + WALL_M, -sy / 2, sy / 2)
        out.append((moved(lid, *pose), top, top + sx * math.sin(angle) + WALL_M))
    return out


def _inward_normals(polygon: np.ndarray) -> np.ndarray:
    """Each edge's normal pointing inside (counterclockwise: the inside is to the left of each edge)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    return np.column_stack([-edges[:, 1], edges[:, 0]])


def _crosses(a: np.ndarray, b: np.ndarray, prism: Prism) -> bool:
    """Whether the segment a-b (3D, table frame) passes through the prism (Liang-Barsky clipping)."""
    polygon, z0, z1 = prism
    d = b - a
    lo, hi = 1e-6, 1.0
    bounds = [(-d[2], a[2] - z0), (d[2], z1 - a[2])]  # p * t <= q for every half-space
    for p0, inward in zip(polygon, _inward_normals(polygon), strict=True):
        bounds.append((-(d[:2] @ inward), (a[:2] - p0) @ inward))
    for p, q in bounds:
        if abs(p) < 1e-12:
            if q < 0:
                return False
            continue
        t = q / p
        if p < 0:
            lo = max(lo, t)
        else:
            hi = min(hi, t)
        if lo > hi:
            return False
    return True


def share_in_sight(scene: Scene, name: str, camera_m: np.ndarray) -> float:
    """The share of points over the object's top that the camera at camera_m (table frame) sees past the others."""
    o = next(x for x in scene.objects if x.name == name)
    polygon, _, top = prisms(o)[0]
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    u, v = np.meshgrid(np.linspace(0.1, 0.9, GRID), np.linspace(0.1, 0.9, GRID))
    xy = lo + np.column_stack([u.ravel(), v.ravel()]) * (hi - lo)
    inside = np.all(((xy[:, None, :] - polygon[None]) * _inward_normals(polygon)).sum(axis=2) >= 0, axis=1)
    points = np.column_stack([xy[inside], np.full(int(inside.sum()), top)])
    others = [p for x in scene.objects if x.name != name for p in prisms(x)]
    seen = [not any(_crosses(point, camera_m, prism) for prism in others) for point in points]
    return float(np.mean(seen)) if seen else 0.0
