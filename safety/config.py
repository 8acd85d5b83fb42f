"""Safety limits (SI units). Defaults are the vendor's; a profile may only make them stricter.

Every value is finite and within physical bounds, checked at load: boxes are ordered and inside the cell, the
collision resolution lies between 1 mrad (finer checks nothing a 1 mm padding would not) and 0.05 rad (coarser
could step over a thin obstacle), so a typo cannot make the gate exhaust memory or check too coarsely.
"""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from drivers.config import Position, StrictModel

VENDOR_MAX_JOINT_VELOCITY = math.radians(180.0)  # [rad/s]
VENDOR_MAX_JOINT_ACCELERATION = math.radians(1146.0)  # [rad/s^2]
VENDOR_MAX_JOINT_JERK = math.radians(28647.0)  # [rad/s^3]
VENDOR_MAX_TCP_SPEED = 1.0  # [m/s]


class BoxRegion(StrictModel):
    """Axis-aligned box in the base frame, within the cell (drivers.config.CELL_EXTENT_M)."""

    name: str = ""
    min_m: Position
    max_m: Position

    @model_validator(mode="after")
    def _ordered(self) -> BoxRegion:
        if any(lo >= hi for lo, hi in zip(self.min_m, self.max_m, strict=True)):
            raise ValueError(f"box {self.name!r}: every min_m must be below max_m ({self.min_m} vs {self.max_m})")
        return self


class SafetyConfig(StrictModel):
    joint_margin_rad: float = Field(default=0.05, ge=0, le=0.5, description="kept from every joint limit")
    max_joint_velocity_rad_s: float = Field(default=VENDOR_MAX_JOINT_VELOCITY, gt=0)
    max_joint_acceleration_rad_s2: float = Field(default=VENDOR_MAX_JOINT_ACCELERATION, gt=0)
    max_joint_jerk_rad_s3: float = Field(default=VENDOR_MAX_JOINT_JERK, gt=0)
    max_tcp_speed_m_s: float = Field(default=VENDOR_MAX_TCP_SPEED, gt=0)
    max_joint_step_rad: float = Field(default=0.04, gt=0, le=0.5, description="largest set-point change per tick")
    padding_m: float = Field(default=0.01, ge=0, le=0.2, description="added to every collision geometry")
    collision_resolution_rad: float = Field(
        default=0.01, ge=0.001, le=0.05, description="max joint motion between checks"
    )
    cloud_voxel_m: float = Field(
        default=0.01, ge=0.002, le=0.1, description="octree cell size of point-cloud obstacles"
    )
    workspace: BoxRegion = BoxRegion(name="workspace", min_m=(-0.35, -0.7, -0.005), max_m=(0.95, 0.7, 1.2))
    keep_out: tuple[BoxRegion, ...] = Field(default=(), max_length=64)

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
