"""Safety limits (SI units). Defaults are the vendor's; a profile may only make them stricter."""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from drivers.config import StrictModel, Vec3

VENDOR_MAX_JOINT_VELOCITY = math.radians(180.0)  # [rad/s]
VENDOR_MAX_JOINT_ACCELERATION = math.radians(1146.0)  # [rad/s^2]
VENDOR_MAX_JOINT_JERK = math.radians(28647.0)  # [rad/s^3]
VENDOR_MAX_TCP_SPEED = 1.0  # [m/s]


class BoxRegion(StrictModel):
    """Axis-aligned box in the base frame."""

    name: str = ""
    min_m: Vec3
    max_m: Vec3

    @model_validator(mode="after")
    def _ordered(self) -> BoxRegion:
        if any(lo >= hi for lo, hi in zip(self.min_m, self.max_m, strict=True)):
            raise ValueError(f"box {self.name!r}: every min_m must be below max_m ({self.min_m} vs {self.max_m})")
        return self


class SafetyConfig(StrictModel):
    joint_margin_rad: float = Field(default=0.05, ge=0, description="kept from every joint limit")
    max_joint_velocity_rad_s: float = Field(default=VENDOR_MAX_JOINT_VELOCITY, gt=0)
    max_joint_acceleration_rad_s2: float = Field(default=VENDOR_MAX_JOINT_ACCELERATION, gt=0)
    max_joint_jerk_rad_s3: float = Field(default=VENDOR_MAX_JOINT_JERK, gt=0)
    max_tcp_speed_m_s: float = Field(default=VENDOR_MAX_TCP_SPEED, gt=0)
    max_joint_step_rad: float = Field(default=0.04, gt=0, description="largest set-point change per tick")
    padding_m: float = Field(default=0.01, ge=0, description="added to every collision geometry")
    collision_resolution_rad: float = Field(default=0.01, gt=0, description="max joint motion between checks")
    cloud_voxel_m: float = Field(default=0.01, gt=0, description="octree cell size of point-cloud obstacles")
    workspace: BoxRegion = BoxRegion(name="workspace", min_m=(-0.35, -0.7, -0.005), max_m=(0.95, 0.7, 1.2))
    keep_out: tuple[BoxRegion, ...] = ()

    @model_validator(mode="after")
    def _within_vendor(self) -> SafetyConfig:
        vendor = {
            "max_joint_velocity_rad_s": VENDOR_MAX_JOINT_VELOCITY,
            "max_joint_acceleration_rad_s2": VENDOR_MAX_JOINT_ACCELERATION,
            "max_joint_jerk_rad_s3": VENDOR_MAX_JOINT_JERK,
            "max_tcp_speed_m_s": VENDOR_MAX_TCP_SPEED,
        }
        for key, bound in vendor.items():
            if getattr(self, key) > bound * (1 + 1e-9):
                raise ValueError(f"{key} = {getattr(self, key):.4g} exceeds the vendor limit {bound:.4g}")
        return self
