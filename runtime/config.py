"""Profiles: YAML files validated into one typed `Profile`.

A profile may `include:` other profiles (paths relative to itself); its sections are deep-merged over theirs,
mappings key by key, anything else replaced. Errors name the file that set the offending key, the key path and
the problem. Relative paths in the config are resolved against the file that wrote them. Files are read with
drivers.files.load_yaml (UTF-8, bounded, a repeated key is an error with its line); one profile reads at most
MAX_PROFILE_FILES files, includes included.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, model_validator

from calibration.config import CalibrationConfig
from drivers.config import CameraConfig, RobotConfig, SimConfig, StrictModel
from drivers.files import InputFileError, load_yaml
from motion.config import MotionConfig
from pipeline.config import PipelineConfig
from safety.config import SafetyConfig

KeyPath = tuple[str, ...]
MAX_PROFILE_FILES = 32
PATH_KEYS: tuple[KeyPath, ...] = (
    ("calibration", "file"),
    ("sim", "scenes_dir"),
    ("runtime", "runs_dir"),
    ("runtime", "estop_latch_file"),
    *((("runtime", "zenoh", "tls", k)) for k in ("root_ca_certificate", "certificate", "private_key")),
)


class ConfigError(ValueError):
    """A profile could not be read or validated; the message lists every problem with file and key."""


class ZenohTlsConfig(StrictModel):
    """TLS for links off the loopback (zenoh transport.link.tls); mutual: both sides present certificates."""

    root_ca_certificate: Path
    certificate: Path
    private_key: Path
    mutual: bool = True


class ZenohConfig(StrictModel):
    """The runtime node listens on `endpoint`; console and e-stop nodes connect to it. Scouting is always off."""

    endpoint: str = Field(default="tcp/127.0.0.1:7447", pattern=r"^(tcp|tls)/[^/]+:\d+$")
    tls: ZenohTlsConfig | None = None
    access_control: dict[str, Any] | None = Field(default=None, description="zenoh access_control block, verbatim")

    @model_validator(mode="after")
    def _loopback_or_tls(self) -> ZenohConfig:
        host = self.endpoint.split("/", 1)[1].rsplit(":", 1)[0]
        if self.endpoint.startswith("tcp/") and host not in ("127.0.0.1", "localhost", "[::1]"):
            raise ValueError(
                f"endpoint {self.endpoint}: plain tcp is for loopback only; use tls/ with runtime.zenoh.tls"
            )
        if self.endpoint.startswith("tls/") and self.tls is None:
            raise ValueError(f"endpoint {self.endpoint} needs runtime.zenoh.tls (certificates)")
        return self


MAX_STATE_BUDGET_S = 3600.0  # an hour in one state is a hung run, and a longer timeout would overflow a wait


class StateBudgets(StrictModel):
    """Seconds each state may last before the run fails; awaiting_confirm is the confirm timeout."""

    capturing: float = Field(default=5.0, gt=0, le=MAX_STATE_BUDGET_S)
    reasoning: float = Field(default=120.0, gt=0, le=MAX_STATE_BUDGET_S)
    grounding: float = Field(default=30.0, gt=0, le=MAX_STATE_BUDGET_S)
    planning: float = Field(default=60.0, gt=0, le=MAX_STATE_BUDGET_S)
    awaiting_confirm: float = Field(default=120.0, gt=0, le=MAX_STATE_BUDGET_S)
    rechecking: float = Field(default=30.0, gt=0, le=MAX_STATE_BUDGET_S)
    executing: float = Field(default=120.0, gt=0, le=MAX_STATE_BUDGET_S)
    verifying: float = Field(default=15.0, gt=0, le=MAX_STATE_BUDGET_S)


class SecondLookConfig(StrictModel):
    """The second look right before moving: capture again, compare with the capture the plan was made from."""

    enabled: bool = True
    depth_change_m: float = Field(
        default=0.01, ge=0.002, le=0.2, description="a pixel changed when its depth changed by more than this"
    )
    min_area_m2: float = Field(
        default=2e-4, ge=1e-6, le=0.1, description="a changed region smaller than this is noise (2 cm^2)"
    )
    target_shift_m: float = Field(
        default=0.005, ge=0, le=0.1, description="the target may have moved this far and the plan still holds"
    )
    target_turn_deg: float = Field(default=5.0, ge=0, le=90, description="... and turned this much")
    max_replans: int = Field(default=2, ge=0, le=5, description="replans after a change before the run refuses")


class RuntimeConfig(StrictModel):
    robot_id: str = Field(default="xarm7", pattern=r"^[A-Za-z0-9_\-]+$", description="Zenoh key prefix part")
    runs_dir: Path = Field(default=Path("runs"), description="run records are written below this folder")
    zenoh: ZenohConfig = ZenohConfig()
    budgets_s: StateBudgets = StateBudgets()
    deadman_timeout_s: float = Field(default=0.2, gt=0, le=1.0, description="e-stop node heartbeat max age")
    heartbeat_rate_hz: float = Field(default=20.0, ge=5.0, le=200.0)
    telemetry_rate_hz: float = Field(default=50.0, ge=50.0, le=250.0, description="joint_state publishing rate")
    estop_node: Literal["external", "in_process"] = Field(
        default="external", description="in_process: a heartbeat thread in the run itself (sim profiles only)"
    )
    verify_position_tol_m: float = Field(default=0.03, gt=0, le=1.0, description="achieved vs goal object translation")
    verify_rotation_tol_deg: float = Field(default=15.0, gt=0, le=180, description="achieved vs goal object rotation")
    verify_lid_shut_tol_deg: float = Field(
        default=12.0, gt=0, le=90, description="close: the lid's seen face at most this far off the table's plane"
    )
    rerun_recording: bool = Field(
        default=True, description="write run.rrd (a Rerun recording) into each run folder when the run has ended"
    )
    estop_latch_file: Path | None = Field(
        default=None,
        description="an e-stop writes it and later runs start ESTOPPED until a reset removes it (set on real robots)",
    )
    second_look: SecondLookConfig = SecondLookConfig()


class Profile(StrictModel):
    name: str = "unnamed"
    robot: RobotConfig = RobotConfig()
    camera: CameraConfig = CameraConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    safety: SafetyConfig = SafetyConfig()
    motion: MotionConfig = MotionConfig()
    pipeline: PipelineConfig = PipelineConfig()
    runtime: RuntimeConfig = RuntimeConfig()
    sim: SimConfig = SimConfig()


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        data = load_yaml(path, "profile")
    except InputFileError as e:
        raise ConfigError(str(e)) from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a profile must be a mapping of sections, got {type(data).__name__}")
    return data


def _merge(base: dict, over: dict, origin: dict[KeyPath, Path], path: Path | None, prefix: KeyPath = ()) -> dict:
    """Deep-merge `over` into `base`; record `path` as the origin of every key it sets (None: keep origins)."""
    out = dict(base)
    for key, value in over.items():
        key_path = (*prefix, str(key))
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value, origin, path, key_path)
        else:
            out[key] = value
            if path is not None:
                for known in [k for k in origin if k[: len(key_path)] == key_path]:
                    del origin[known]
        if path is not None:
            origin[key_path] = path
    return out


def _load_merged(path: Path, origin: dict[KeyPath, Path], stack: tuple[Path, ...], loaded: list[Path]) -> dict:
    """The profile at path with its includes merged under it; `stack` holds the files including it."""
    try:
        path = path.resolve()
    except (OSError, ValueError, RuntimeError) as e:  # a NUL byte, a symlink loop
        raise ConfigError(
            f"{stack[-1] if stack else path}: include: {str(path)!r} is not a usable path ({e})"
        ) from None
    if path in stack:
        chain = " -> ".join(str(p) for p in (*stack, path))
        raise ConfigError(f"{path}: include cycle ({chain})")
    loaded.append(path)
    if len(loaded) > MAX_PROFILE_FILES:
        raise ConfigError(f"{path}: includes read more than {MAX_PROFILE_FILES} files (from {loaded[0]})")
    try:
        data = _read_yaml(path)
    except ConfigError as e:
        raise (ConfigError(f"{stack[-1]}: include: {e}") if stack else e) from None
    includes = data.pop("include", [])
    if isinstance(includes, str):
        includes = [includes]
    if not isinstance(includes, list) or not all(isinstance(i, str) for i in includes):
        raise ConfigError(f"{path}: include: must be a path or a list of paths")
    merged: dict = {}
    for inc in includes:  # each include records its own keys' origins
        merged = _merge(merged, _load_merged(path.parent / inc, origin, (*stack, path), loaded), origin, None)
    return _merge(merged, data, origin, path)


def _origin_of(loc: KeyPath, origin: dict[KeyPath, Path], default: Path) -> Path:
    for n in range(len(loc), 0, -1):
        if loc[:n] in origin:
            return origin[loc[:n]]
    return default


def _resolve_paths(data: dict, origin: dict[KeyPath, Path], default: Path) -> None:
    for key_path in PATH_KEYS:
        node = data
        for key in key_path[:-1]:
            node = node.get(key) if isinstance(node, dict) else None
        if not isinstance(node, dict) or not isinstance(node.get(key_path[-1]), str):
            continue
        file = _origin_of(key_path, origin, default)
        try:
            value = Path(node[key_path[-1]]).expanduser()
            if not value.is_absolute():
                value = (file.parent / value).resolve()
        except (RuntimeError, ValueError, OSError) as e:  # ~unknown-user, a NUL byte, a symlink loop
            raise ConfigError(f"{file}: {'.'.join(key_path)}: not a usable path ({e})") from None
        node[key_path[-1]] = str(value)


def load_profile(path: str | Path, overrides: dict[str, Any] | None = None) -> Profile:
    """Load and validate a profile; `overrides` (nested mapping) is merged last, as if from the command line."""
    path = Path(path)
    origin: dict[KeyPath, Path] = {}
    data = _load_merged(path, origin, (), [])
    sim = data.setdefault("sim", {})
    if isinstance(sim, dict) and "scenes_dir" not in sim:
        sim["scenes_dir"] = "scenes"  # default: next to the profile
    _resolve_paths(data, origin, path.resolve())
    if overrides:
        data = _merge(data, overrides, origin, Path("<command line>"))
    try:
        return Profile.model_validate(data)
    except ValidationError as e:
        lines = []
        for err in e.errors():
            loc = tuple(str(p) for p in err["loc"])
            file = _origin_of(loc, origin, path.resolve())
            key = ".".join(loc) or "<top level>"
            msg = "unknown key (not allowed here)" if err["type"] == "extra_forbidden" else err["msg"]
            msg = msg.removeprefix("Value error, ")
            lines.append(f"{file}: {key}: {msg}")
        raise ConfigError("invalid profile:\n  " + "\n  ".join(lines)) from None
