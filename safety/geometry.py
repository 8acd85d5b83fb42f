"""Collision primitives: the robot's, read straight from the description YAML (true capsules, not the URDF's
cylinder + spheres), and the world's. Both collision backends are built from these same objects.

A Primitive is a shape rigidly attached to a frame (`link`; "world" for the base frame) at T_link_geom.
Shape conventions follow the description: box = full size, cylinder and capsule along the local z axis
(length = cylinder height / capsule segment length), sphere = radius.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.description.spec import Box, Capsule, Cylinder, RobotSpec, Shape

Kind = Literal["box", "cylinder", "capsule", "sphere"]
WORLD = "world"


def pose(xyz=(0.0, 0.0, 0.0), R: np.ndarray | None = None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    T[:3, 3] = xyz
    return T


def turn_about(point: np.ndarray, axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """4x4 rigid turn by angle_rad (right hand) about the line through `point` along `axis` (a hinge, an axis of
    symmetry)."""
    R = Rotation.from_rotvec(angle_rad * np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)).as_matrix()
    return pose(np.asarray(point, dtype=np.float64) - R @ point, R)


def pose_rpy(xyz, rpy) -> np.ndarray:
    """Pose from a position and fixed-axis roll-pitch-yaw (the URDF convention)."""
    return pose(xyz, Rotation.from_euler("xyz", rpy).as_matrix())


@dataclass(frozen=True)
class Primitive:
    name: str
    link: str  # frame the shape is attached to; WORLD = base frame
    kind: Kind
    size: tuple[float, ...]  # box (x, y, z); cylinder/capsule (radius, length); sphere (radius,)
    T_link_geom: np.ndarray = field(default_factory=lambda: np.eye(4))

    def padded(self, padding_m: float) -> Primitive:
        """The shape grown by padding_m on every side (a box grows on each face, a capsule in radius)."""
        if padding_m == 0:
            return self
        if self.kind == "box":
            size = tuple(s + 2 * padding_m for s in self.size)
        elif self.kind == "cylinder":
            size = (self.size[0] + padding_m, self.size[1] + 2 * padding_m)
        elif self.kind == "capsule":
            size = (self.size[0] + padding_m, self.size[1])
        else:
            size = (self.size[0] + padding_m,)
        return replace(self, size=size)

    def bounding_radius(self) -> float:
        """Radius of a sphere about the shape's centre that encloses it."""
        if self.kind == "box":
            return float(np.linalg.norm(self.size) / 2)
        if self.kind == "cylinder":
            return float(np.hypot(self.size[0], self.size[1] / 2))
        if self.kind == "capsule":
            return self.size[0] + self.size[1] / 2
        return self.size[0]

    def contains(self, points_geom: np.ndarray) -> np.ndarray:
        """Which points (N, 3), given in the shape's own frame, lie inside it."""
        p = np.asarray(points_geom)
        if self.kind == "box":
            return np.all(np.abs(p) <= np.asarray(self.size) / 2, axis=1)
        if self.kind == "sphere":
            return np.einsum("ij,ij->i", p, p) <= self.size[0] ** 2
        r, length = self.size
        if self.kind == "cylinder":
            return (np.hypot(p[:, 0], p[:, 1]) <= r) & (np.abs(p[:, 2]) <= length / 2)
        z = np.clip(p[:, 2], -length / 2, length / 2)
        return np.hypot(np.hypot(p[:, 0], p[:, 1]), p[:, 2] - z) <= r


def from_spec_shape(name: str, link: str, shape: Shape, T_link_frame: np.ndarray | None = None) -> Primitive:
    """A description shape as a Primitive; T_link_frame places the shape's frame when it is not the link's."""
    base = np.eye(4) if T_link_frame is None else T_link_frame
    if isinstance(shape, Box):
        return Primitive(name, link, "box", tuple(shape.size), base @ pose(shape.xyz))
    if isinstance(shape, Cylinder):
        return Primitive(name, link, "cylinder", (shape.radius, shape.length), base @ pose(shape.xyz))
    if isinstance(shape, Capsule):
        return Primitive(
            name, link, "capsule", (shape.radius, shape.length), base @ pose(shape.center, shape.rotation())
        )
    raise TypeError(f"unsupported shape {shape!r}")


def robot_primitives(spec: RobotSpec) -> list[Primitive]:
    """Every collision primitive of the arm, the gripper body and both fingers, unpadded."""
    prims = [
        from_spec_shape(f"{link}/{shape.name or i}", link, shape)
        for link, desc in spec.links.items()
        for i, shape in enumerate(desc.collision)
    ]
    prims += [
        from_spec_shape(f"{finger}/{shape.name or i}", finger, shape)
        for finger in spec.gripper.finger_links
        for i, shape in enumerate(spec.gripper.finger_collision)
    ]
    return prims


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    return points @ T[:3, :3].T + T[:3, 3]
