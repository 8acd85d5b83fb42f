"""Write the robot into a MuJoCo model (MJCF) from the description spec.

The servo model: every arm joint has a stiff position actuator with gravity compensation on the links, which
is how the xArm behaves in servo mode (it tracks the latest set-point). The fingers are two position-driven
slide joints whose value is half the finger gap; grasping holds by friction on the pads.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.description.spec import Box, Capsule, Cylinder, Inertial, RobotSpec, Shape

# Servo gains of the simulated controller: a position loop [N m / rad] plus a velocity loop whose set-point is
# the set-point's rate of change (feed-forward), so a moving set-point is tracked without lag. Force limits are
# 2x the rated effort so tracking stays tight under load (the real controller's inner loops are stiffer).
ARM_KP = (4000.0, 4000.0, 3000.0, 3000.0, 2000.0, 1500.0, 1500.0)
ARM_KV_RATIO = 0.03
FINGER_KP = 2000.0  # [N / m]
ROBOT_RGBA = "0.92 0.92 0.92 1"
GRIPPER_RGBA = "0.25 0.25 0.27 1"

# contype/conaffinity bits: robot geoms never touch each other in the sim (self-collision is the safety
# layer's job), but touch the table and objects.
ROBOT_CONTACT = {"contype": "2", "conaffinity": "1"}


def _f(values) -> str:
    return " ".join(f"{float(v):.9g}" for v in np.atleast_1d(values))


def _quat_wxyz(rpy) -> str:
    x, y, z, w = Rotation.from_euler("xyz", rpy).as_quat()
    return _f((w, x, y, z))


def _inertial(body: ET.Element, inertial: Inertial) -> None:
    ixx, ixy, ixz, iyy, iyz, izz = inertial.inertia
    ET.SubElement(
        body, "inertial", pos=_f(inertial.com), mass=_f(inertial.mass), fullinertia=_f((ixx, iyy, izz, ixy, ixz, iyz))
    )


def _geom(body: ET.Element, name: str, shape: Shape, rgba: str, **extra: str) -> None:
    attrs = {"name": name, "rgba": rgba, **ROBOT_CONTACT, **extra}
    if isinstance(shape, Box):
        ET.SubElement(body, "geom", type="box", size=_f(np.asarray(shape.size) / 2), pos=_f(shape.xyz), **attrs)
    elif isinstance(shape, Cylinder):
        ET.SubElement(
            body, "geom", type="cylinder", size=_f((shape.radius, shape.length / 2)), pos=_f(shape.xyz), **attrs
        )
    elif isinstance(shape, Capsule):
        ET.SubElement(body, "geom", type="capsule", size=_f(shape.radius), fromto=_f((*shape.p0, *shape.p1)), **attrs)


def add_robot(worldbody: ET.Element, actuators: ET.Element, spec: RobotSpec) -> None:
    """Append the robot's bodies under `worldbody` and its servos under `actuators`."""
    bodies: dict[str, ET.Element] = {}
    base = ET.SubElement(worldbody, "body", name=spec.base_link)
    bodies[spec.base_link] = base

    def fill(body: ET.Element, link_name: str, rgba: str) -> None:
        link = spec.links[link_name]
        if link.inertial:
            _inertial(body, link.inertial)
        for i, shape in enumerate(link.collision):
            _geom(body, f"{link_name}_{shape.name or i}", shape, rgba)

    fill(base, spec.base_link, ROBOT_RGBA)
    for j, kp in zip(spec.arm_joints, ARM_KP, strict=True):
        body = ET.SubElement(
            bodies[j.parent], "body", name=j.child, pos=_f(j.xyz), quat=_quat_wxyz(j.rpy), gravcomp="1"
        )
        bodies[j.child] = body
        ET.SubElement(
            body,
            "joint",
            name=j.name,
            type="hinge",
            axis="0 0 1",
            range=_f((j.lower, j.upper)),
            damping=_f(j.damping),
            armature="0.1",
        )
        fill(body, j.child, ROBOT_RGBA)
        ET.SubElement(
            actuators,
            "position",
            name=f"servo_{j.name}",
            joint=j.name,
            kp=_f(kp),
            forcerange=_f((-2 * j.effort, 2 * j.effort)),
            ctrlrange=_f((j.lower, j.upper)),
        )
        ET.SubElement(
            actuators,
            "velocity",
            name=f"velocity_{j.name}",
            joint=j.name,
            kv=_f(kp * ARM_KV_RATIO),
            forcerange=_f((-2 * j.effort, 2 * j.effort)),
        )
    for j in spec.fixed_joints:
        body = ET.SubElement(
            bodies[j.parent], "body", name=j.child, pos=_f(j.xyz), quat=_quat_wxyz(j.rpy), gravcomp="1"
        )
        bodies[j.child] = body
        fill(body, j.child, GRIPPER_RGBA if "gripper" in j.child else ROBOT_RGBA)
    ET.SubElement(bodies[spec.tcp_link], "site", name="tcp", size="0.004", rgba="1 0 0 1")

    g = spec.gripper
    for side, (joint, link_name) in enumerate(zip(g.finger_joints, g.finger_links, strict=True)):
        body = ET.SubElement(
            bodies[g.parent], "body", name=link_name, quat=_quat_wxyz((0, 0, np.pi * side)), gravcomp="1"
        )
        ET.SubElement(body, "inertial", pos="0 0.015 0.12", mass=_f(g.finger_mass), diaginertia="5e-5 5e-5 2e-5")
        ET.SubElement(
            body,
            "joint",
            name=joint,
            type="slide",
            axis="0 1 0",
            range=_f((g.min_width_m / 2, g.max_width_m / 2)),
            damping="20",
            armature="0.01",
        )
        for i, shape in enumerate(g.finger_collision):
            _geom(
                body,
                f"{link_name}_{shape.name or i}",
                shape,
                GRIPPER_RGBA,
                friction="1.5 0.02 0.002",
                condim="4",
                solref="0.005 1",
                priority="1",
            )
        ET.SubElement(
            actuators,
            "position",
            name=f"servo_{joint}",
            joint=joint,
            kp=_f(FINGER_KP),
            kv=_f(FINGER_KP * 0.05),
            forcerange=_f((-g.max_force_n, g.max_force_n)),
            ctrlrange=_f((g.min_width_m / 2, g.max_width_m / 2)),
        )
