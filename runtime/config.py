"""Profiles: YAML files validated into one typed `Profile`.

A profile may `include:` other profiles (paths relative to itself); its sections are deep-merged over theirs,
mappings key by key, anything else replaced. Errors name the file that set the offending key, the key path and
the problem. Relative paths in the config are resolved against the file that wrote them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml
from pydantic import Field, ValidationError

from calibration.config import CalibrationConfig
from drivers.config import CameraConfig, RobotConfig, SimConfig, StrictModel
from pipeline.config import PipelineConfig
from safety.config import SafetyConfig

KeyPath = tuple[str, ...]
PATH_KEYS: tuple[KeyPath, ...] = (("calibration", "file"), ("sim", "scenes_dir"), ("runtime", "runs_dir"))


class ConfigError(ValueError):
    """A profile could not be read or validated; the message lists every problem with file and key."""


class RuntimeConfig(StrictModel):
    robot_id: str = Field(default="xarm7", pattern=r"^[A-Za-z0-9_\-]+$", description="Zenoh key prefix part")
    runs_dir: Path = Field(default=Path("runs"), description="run records are written below this folder")


class Profile(StrictModel):
    name: str = "unnamed"
    robot: RobotConfig = RobotConfig()
    camera: CameraConfig = CameraConfig()
    calibration: CalibrationConfig = CalibrationConfig()
    safety: SafetyConfig = SafetyConfig()
    pipeline: PipelineConfig = PipelineConfig()
    runtime: RuntimeConfig = RuntimeConfig()
    sim: SimConfig = SimConfig()


def _read_yaml(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read profile ({e.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f":{mark.line + 1}:{mark.column + 1}" if mark else ""
        raise ConfigError(f"{path}{where}: invalid YAML ({getattr(e, 'problem', e)})") from None
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


def _load_merged(path: Path, origin: dict[KeyPath, Path], stack: tuple[Path, ...]) -> dict:
    path = path.resolve()
    if path in stack:
        chain = " -> ".join(str(p) for p in (*stack, path))
        raise ConfigError(f"{path}: include cycle ({chain})")
    data = _read_yaml(path)
    includes = data.pop("include", [])
    if isinstance(includes, str):
        includes = [includes]
    if not isinstance(includes, list) or not all(isinstance(i, str) for i in includes):
        raise ConfigError(f"{path}: include: must be a path or a list of paths")
    merged: dict = {}
    for inc in includes:  # each include records its own keys' origins
        merged = _merge(merged, _load_merged(path.parent / inc, origin, (*stack, path)), origin, None)
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
        value = Path(node[key_path[-1]]).expanduser()
        if not value.is_absolute():
            value = _origin_of(key_path, origin, default).parent / value
        node[key_path[-1]] = str(value)


def load_profile(path: str | Path, overrides: dict[str, Any] | None = None) -> Profile:
    """Load and validate a profile; `overrides` (nested mapping) is merged last, as if from the command line."""
    path = Path(path)
    origin: dict[KeyPath, Path] = {}
    data = _load_merged(path, origin, ())
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
