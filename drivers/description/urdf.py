"""Write the URDF of the robot from the description spec.

URDF has no capsule primitive, so a capsule becomes a cylinder and two end spheres (exact same volume).
The gripper fingers are prismatic joints whose value is half the finger gap; the right finger mimics the left.
"""

from __future__ import annotations

import warnings
import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.description.spec import Box, Capsule, Cylinder, Inertial, RobotSpec, Shape


def _fmt(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.atleast_1d(values))


def _origin(parent: ET.Element, xyz, rpy=(0.0, 0.0, 0.0)) -> None:
    ET.SubElement(parent, "origin", xyz=_fmt(xyz), rpy=_fmt(rpy))


def _inertial(link: ET.Element, inertial: Inertial) -> None:
    el = ET.SubElement(link, "inertial")
    _origin(el, inertial.com)
    ET.SubElement(el, "mass", value=_fmt(inertial.mass))
    ixx, ixy, ixz, iyy, iyz, izz = inertial.inertia
    ET.SubElement(
        el, "inertia", ixx=_fmt(ixx), ixy=_fmt(ixy), ixz=_fmt(ixz), iyy=_fmt(iyy), iyz=_fmt(iyz), izz=_fmt(izz)
    )


def _collision(link: ET.Element, name: str, xyz, rpy, geometry: tuple[str, dict[str, str]]) -> None:
    el = ET.SubElement(link, "collision", name=name)
    _origin(el, xyz, rpy)
    ET.SubElement(ET.SubElement(el, "geometry"), geometry[0], **geometry[1])


def _shape(link: ET.Element, link_name: str, index: int, shape: Shape) -> None:
    base = f"{link_name}_{shape.name or index}"
    if isinstance(shape, Box):
        _collision(link, base, shape.xyz, (0, 0, 0), ("box", {"size": _fmt(shape.size)}))
    elif isinstance(shape, Cylinder):
        _collision(
            link, base, shape.xyz, (0, 0, 0), ("cylinder", {"radius": _fmt(shape.radius), "length": _fmt(shape.length)})
        )
    elif isinstance(shape, Capsule):
        with warnings.catch_warnings():  # a capsule along x is a gimbal lock; the angles stay exact
            warnings.simplefilter("ignore", UserWarning)
            rpy = Rotation.from_matrix(shape.rotation()).as_euler("xyz")
        _collision(
            link, base, shape.center, rpy, ("cylinder", {"radius": _fmt(shape.radius), "length": _fmt(shape.length)})
        )
        for end, point in (("a", shape.p0), ("b", shape.p1)):
            _collision(link, f"{base}_cap_{end}", point, (0, 0, 0), ("sphere", {"radius": _fmt(shape.radius)}))


def _finger_inertial(mass: float) -> Inertial:
    # a 3 x 3 x 7 cm slab of the finger's mass, centred on the pad
    a, b, c = 0.03, 0.03, 0.07
    return Inertial(
        mass=mass,
        com=(0.0, 0.015, 0.12),
        inertia=(mass * (b * b + c * c) / 12, 0, 0, mass * (a * a + c * c) / 12, 0, mass * (a * a + b * b) / 12),
    )


def build_urdf(spec: RobotSpec) -> str:
    robot = ET.Element("robot", name=spec.name)
    for name, link in spec.links.items():
        el = ET.SubElement(robot, "link", name=name)
        if link.inertial:
            _inertial(el, link.inertial)
        for i, shape in enumerate(link.collision):
            _shape(el, name, i, shape)
    for j in spec.arm_joints:
        el = ET.SubElement(robot, "joint", name=j.name, type="revolute")
        ET.SubElement(el, "parent", link=j.parent)
        ET.SubElement(el, "child", link=j.child)
        _origin(el, j.xyz, j.rpy)
        ET.SubElement(el, "axis", xyz="0 0 1")
        ET.SubElement(
            el, "limit", lower=_fmt(j.lower), upper=_fmt(j.upper), velocity=_fmt(j.velocity), effort=_fmt(j.effort)
        )
        ET.SubElement(el, "dynamics", damping=_fmt(j.damping), friction="1")
    for j in spec.fixed_joints:
        el = ET.SubElement(robot, "joint", name=j.name, type="fixed")
        ET.SubElement(el, "parent", link=j.parent)
        ET.SubElement(el, "child", link=j.child)
        _origin(el, j.xyz, j.rpy)
    g = spec.gripper
    for side, (joint, link_name) in enumerate(zip(g.finger_joints, g.finger_links, strict=True)):
        link = ET.SubElement(robot, "link", name=link_name)
        _inertial(link, _finger_inertial(g.finger_mass))
        for i, shape in enumerate(g.finger_collision):
            _shape(link, link_name, i, shape)
        el = ET.SubElement(robot, "joint", name=joint, type="prismatic")
        ET.SubElement(el, "parent", link=g.parent)
        ET.SubElement(el, "child", link=link_name)
        _origin(el, (0, 0, 0), (0, 0, np.pi * side))  # right finger frame turned so +y points outward
        ET.SubElement(el, "axis", xyz="0 1 0")
        ET.SubElement(
            el,
            "limit",
            lower=_fmt(g.min_width_m / 2),
            upper=_fmt(g.max_width_m / 2),
            velocity="0.1",
            effort=_fmt(g.max_force_n),
        )
        if side:
            ET.SubElement(el, "mimic", joint=g.finger_joints[0], multiplier="1", offset="0")
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
