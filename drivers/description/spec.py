"""Typed, validated view of the robot description YAML (xarm7_gripper.yaml)."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from drivers.files import load_yaml

DEFAULT_SPEC = Path(__file__).with_name("xarm7_gripper.yaml")

Vec3 = tuple[float, float, float]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Inertial(_Strict):
    mass: float = Field(gt=0)
    com: Vec3
    inertia: tuple[float, float, float, float, float, float]  # ixx ixy ixz iyy iyz izz [kg m^2]


class Box(_Strict):
    type: Literal["box"]
    size: Vec3
    xyz: Vec3 = (0.0, 0.0, 0.0)
    name: str = ""


class Cylinder(_Strict):
    """Cylinder along the local z axis, centred at xyz."""

    type: Literal["cylinder"]
    radius: float = Field(gt=0)
    length: float = Field(gt=0)
    xyz: Vec3 = (0.0, 0.0, 0.0)
    name: str = ""


class Capsule(_Strict):
    """Segment p0-p1 swept by a sphere of the given radius."""

    type: Literal["capsule"]
    radius: float = Field(gt=0)
    p0: Vec3
    p1: Vec3
    name: str = ""

    @property
    def length(self) -> float:
        return float(np.linalg.norm(np.subtract(self.p1, self.p0)))

    @property
    def center(self) -> np.ndarray:
        return (np.asarray(self.p0) + np.asarray(self.p1)) / 2

    def rotation(self) -> np.ndarray:
        """Rotation whose z axis runs along p0 -> p1 (identity for a degenerate segment)."""
        return rotation_z_to(np.subtract(self.p1, self.p0))


Shape = Annotated[Box | Cylinder | Capsule, Field(discriminator="type")]


class Link(_Strict):
    inertial: Inertial | None = None
    collision: tuple[Shape, ...] = ()


class ArmJoint(_Strict):
    name: str
    parent: str
    child: str
    xyz: Vec3
    rpy: Vec3
    lower: float
    upper: float
    velocity: float = Field(gt=0)
    effort: float = Field(gt=0)
    damping: float = Field(ge=0)

    @model_validator(mode="after")
    def _ordered(self) -> ArmJoint:
        if self.lower >= self.upper:
            raise ValueError(f"{self.name}: lower limit {self.lower} must be below upper {self.upper}")
        return self


class FixedJoint(_Strict):
    name: str
    parent: str
    child: str
    xyz: Vec3
    rpy: Vec3


class GapTable(_Strict):
    drive_rad: tuple[float, ...]
    gap_m: tuple[float, ...]


class GripperSpec(_Strict):
    parent: str
    finger_joints: tuple[str, str]
    finger_links: tuple[str, str]
    finger_mass: float = Field(gt=0)
    max_force_n: float = Field(gt=0)
    drive_angle_to_gap_m: GapTable
    sdk_open: int
    finger_collision: tuple[Shape, ...]

    @property
    def max_width_m(self) -> float:
        return max(self.drive_angle_to_gap_m.gap_m)

    @property
    def min_width_m(self) -> float:
        return min(self.drive_angle_to_gap_m.gap_m)

    def sdk_to_width(self, sdk_position: float) -> float:
        """SDK gripper position (0 closed .. sdk_open open) -> finger gap [m]."""
        drive = (self.sdk_open - float(np.clip(sdk_position, 0, self.sdk_open))) / 1000.0
        t = self.drive_angle_to_gap_m
        return float(np.interp(drive, t.drive_rad, t.gap_m))

    def width_to_sdk(self, width_m: float) -> float:
        """Finger gap [m] -> SDK gripper position, clamped to the stroke."""
        t = self.drive_angle_to_gap_m
        # gap decreases with drive angle: interpolate on the reversed table
        drive = float(np.interp(width_m, t.gap_m[::-1], t.drive_rad[::-1]))
        return self.sdk_open - drive * 1000.0


class RobotSpec(_Strict):
    name: str
    base_link: str
    tcp_link: str
    flange_link: str
    links: dict[str, Link]
    arm_joints: tuple[ArmJoint, ...]
    fixed_joints: tuple[FixedJoint, ...]
    gripper: GripperSpec
    home_q: tuple[float, ...]

    @model_validator(mode="after")
    def _consistent(self) -> RobotSpec:
        known = set(self.links)
        for j in (*self.arm_joints, *self.fixed_joints):
            for end in (j.parent, j.child):
                if end not in known:
                    raise ValueError(f"joint {j.name} names unknown link {end!r}")
        if len(self.home_q) != len(self.arm_joints):
            raise ValueError(f"home_q has {len(self.home_q)} values for {len(self.arm_joints)} joints")
        return self

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.arm_joints)

    @property
    def lower(self) -> np.ndarray:
        return np.array([j.lower for j in self.arm_joints])

    @property
    def upper(self) -> np.ndarray:
        return np.array([j.upper for j in self.arm_joints])

    @property
    def velocity_limits(self) -> np.ndarray:
        return np.array([j.velocity for j in self.arm_joints])


def rotation_z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation matrix whose third column is the unit vector of `direction`."""
    z = np.asarray(direction, dtype=np.float64)
    n = np.linalg.norm(z)
    if n < 1e-12:
        return np.eye(3)
    z = z / n
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


@cache
def load_robot_spec(path: Path = DEFAULT_SPEC) -> RobotSpec:
    return RobotSpec.model_validate(load_yaml(path, "robot description"))
