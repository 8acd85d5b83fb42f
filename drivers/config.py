"""Configuration of the devices: robot, camera and the simulated world (validated, unknown keys rejected).

Every float in every section is finite (NaN and inf are refused at load), and every value with a physical
meaning is bounded to what that meaning allows, so an absurd number is an error naming its key, not a hang or an
exhausted memory later.
"""

from __future__ import annotations

from ipaddress import IPv4Address
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

Vec3 = tuple[float, float, float]
Joints7 = tuple[float, float, float, float, float, float, float]
CELL_EXTENT_M = 10.0  # no position in a robot cell lies farther from the base than this
Coordinate = Annotated[float, Field(ge=-CELL_EXTENT_M, le=CELL_EXTENT_M)]
Position = tuple[Coordinate, Coordinate, Coordinate]  # [m], within the cell


class StrictModel(BaseModel):
    """Base of every config section: unknown keys are errors, floats are finite, values are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class RobotConfig(StrictModel):
    kind: Literal["sim", "xarm7"] = "sim"
    ip: IPv4Address | None = Field(default=None, description="xArm controller address (kind xarm7)")
    home_q_rad: Joints7 | None = Field(default=None, description="ready posture; default: the description's")
    control_rate_hz: float = Field(default=100.0, ge=10.0, le=250.0, description="servo streaming rate")
    tracking_error_max_rad: float = Field(default=0.05, gt=0, le=0.5, description="abort if |q_cmd - q| exceeds this")
    collision_sensitivity: int = Field(default=3, ge=1, le=5, description="xArm collision detection 1..5 (3 vendor)")
    payload_kg: float = Field(default=0.82, ge=0, le=3.5, description="tool + load mass (xArm Gripper: 0.82 kg)")
    payload_cog_m: Vec3 = Field(default=(0.0, 0.0, 0.048), description="tool + load centre of mass, flange frame")
    gripper_speed: int = Field(default=1500, ge=1, le=5000, description="xArm Gripper speed, SDK units (r/min)")
    servo_late_s: float = Field(
        default=0.05, gt=0, le=1.0, description="a servo call slower than this is logged as late"
    )
    emulated: bool = Field(
        default=False,
        description="kind xarm7 only: start the xArm controller emulator at robot.ip (loopback) over the MuJoCo "
        "twin, in this process, and drive it through the real SDK",
    )

    @model_validator(mode="after")
    def _needs_ip(self) -> RobotConfig:
        if self.kind == "xarm7" and self.ip is None:
            raise ValueError("robot.kind 'xarm7' needs robot.ip (the controller's IPv4 address)")
        if self.emulated and self.kind != "xarm7":
            raise ValueError(
                f"robot.emulated emulates the xArm controller: needs robot.kind 'xarm7', not {self.kind!r}"
            )
        if self.emulated and not self.ip.is_loopback:
            raise ValueError(f"robot.emulated: the emulator listens on loopback only; robot.ip {self.ip} is not")
        return self

    @property
    def simulated(self) -> bool:
        """The MuJoCo twin is behind this robot (the sim arm, or the real driver against the emulator)."""
        return self.kind == "sim" or self.emulated


class SimCameraConfig(StrictModel):
    """Pose and noise of the simulated Femto Bolt (its ground-truth extrinsics)."""

    position_m: Position = (1.10, 0.0, 0.80)
    look_at_m: Position = (0.40, 0.0, 0.05)
    horizontal_fov_deg: float = Field(default=80.0, gt=10.0, lt=150.0, description="Femto Bolt colour: 80 deg")
    depth_noise_sigma_m: float = Field(default=0.0015, ge=0, le=0.1, description="noise std at 1 m; grows with range")
    edge_invalid_jump_m: float = Field(default=0.04, gt=0, le=1.0, description="depth jump that marks a pixel invalid")
    mount: Literal["world", "flange"] = Field(default="world", description="flange: eye-in-hand (moves with link7)")
    flange_xyz_m: Position = Field(default=(0.0, 0.11, 0.05), description="mount 'flange': T_flange_camera position")
    flange_rpy_rad: Vec3 = Field(default=(0.26, 0.0, 0.0), description="mount 'flange': optical frame rpy (xyz)")


class CameraConfig(StrictModel):
    kind: Literal["sim", "femto_bolt"] = "sim"
    width_px: int = Field(default=640, ge=64, le=3840, description="colour width; depth is aligned to it")
    height_px: int = Field(default=360, ge=48, le=2160)
    fps: int = Field(default=30, ge=5, le=30)
    depth_mode: Literal["NFOV_UNBINNED", "NFOV_BINNED", "WFOV_BINNED", "WFOV_UNBINNED"] = "NFOV_UNBINNED"
    min_depth_m: float = Field(default=0.5, gt=0, le=20.0, description="nearer depth is invalid (NFOV: 0.5 m)")
    max_depth_m: float = Field(default=3.86, gt=0, le=20.0, description="farther depth is invalid (NFOV: 3.86 m)")
    read_timeout_s: float = Field(default=1.0, gt=0, le=60.0)
    max_frame_age_s: float = Field(default=0.2, gt=0, le=5.0, description="older frames are stale")
    serial: str | None = Field(default=None, description="Femto Bolt serial; None = the only one attached")
    sim: SimCameraConfig = SimCameraConfig()

    @model_validator(mode="after")
    def _range(self) -> CameraConfig:
        if self.min_depth_m >= self.max_depth_m:
            raise ValueError(f"min_depth_m {self.min_depth_m} must be below max_depth_m {self.max_depth_m}")
        return self


class SimFaultsConfig(StrictModel):
    """Fault injection for tests and rehearsal; times are simulation seconds after connect."""

    camera_drop_every_n: int = Field(default=0, ge=0, description="drop every n-th frame (0: never)")
    camera_timeout_after_s: float | None = Field(default=None, ge=0, description="camera stops delivering")
    arm_error_at_s: float | None = Field(default=None, ge=0)
    arm_error_code: int = Field(default=31, description="controller error raised at arm_error_at_s")
    servo_stall_at_s: float | None = Field(default=None, ge=0, description="one servo call blocks here")
    servo_stall_s: float = Field(default=0.2, ge=0, le=60.0)


BoardSide = Annotated[float, Field(gt=0, le=2.0)]  # [m]


class SimBoardConfig(StrictModel):
    """A printed calibration board in the sim (hand-eye): a thin visual-only box with the board image on its face.

    The pose is that of OpenCV's board frame (origin at the first square's outer corner, z out of the back) in
    the parent: the flange link (eye-to-hand, board carried by the arm) or the base (eye-in-hand, on the table).
    """

    texture: Path = Field(description="PNG of the board, exactly its printed extent (no margin)")
    size_m: tuple[BoardSide, BoardSide] = Field(description="printed extent along the board's x and y [m]")
    mount: Literal["flange", "table"] = "flange"
    xyz_m: Position = (0.0, 0.0, 0.0)
    rpy_rad: Vec3 = (0.0, 0.0, 0.0)
    thickness_m: float = Field(default=0.004, gt=0, le=0.1)


class SimConfig(StrictModel):
    scene: str = Field(
        default="tabletop",
        description="scene name (<scenes_dir>/<scene>.yaml), a scene file path (*.yaml), or gen:SEED (generated)",
    )
    scenes_dir: Path = Path("scenes")
    seed: int = Field(default=0, ge=0, lt=2**63)
    physics_dt_s: float = Field(default=0.002, gt=0, le=0.01)
    realtime: bool = Field(default=True, description="physics advances with the wall clock on its own thread")
    faults: SimFaultsConfig = SimFaultsConfig()
    board: SimBoardConfig | None = Field(default=None, description="calibration board (hand-eye on the sim)")

    @property
    def scene_file(self) -> Path:
        return self.scenes_dir / f"{self.scene}.yaml"
