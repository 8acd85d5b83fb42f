"""The gate on files: TRAJ.json (+ optional WORLD.json) -> GateReport, for `goalvla check-trajectory`.

TRAJ.json: {"joint_names": [...7 names in robot order], "dt": seconds > 0, "positions": [[7 rad] * N],
            "gripper_events": [{"time_s": t, "kind": "open"|"close"|"wait", "width_m": w, "duration_s": d}]}
(gripper_events optional). Unknown keys, NaN/inf, a missing or out-of-range dt (0.1 ms .. 10 s), ragged rows or
the wrong joints make the input unusable, and so does a file that drivers.files.load_json refuses (not UTF-8,
over its size, nesting or value bounds, a duplicate key): InputError, which names the file, key and problem.
Positions may be any finite numbers: absurd ones (1e300 rad) are the gate's violations, found without expanding.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from drivers.files import InputFileError, load_json
from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.gate import TrajectoryError, validate
from safety.robot_model import RobotModel
from safety.trajectory import GripperEvent, JointTrajectory
from safety.violations import GateReport
from safety.world import WorldFileError, load_world_file


class InputError(InputFileError):
    """An input file is unusable; it names the file, the key (when one is to blame) and the problem."""


class _Input(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class GripperEventIn(_Input):
    time_s: Annotated[float, Field(ge=0, le=1e6)]
    kind: Literal["open", "close", "wait"]
    width_m: Annotated[float, Field(ge=0, le=1.0)] = 0.0
    duration_s: Annotated[float, Field(ge=0, le=3600)] = 0.0


class TrajectoryFile(_Input):
    joint_names: Annotated[list[Annotated[str, Field(max_length=64)]], Field(max_length=64)]
    dt: Annotated[float, Field(ge=1e-4, le=10.0)]
    positions: Annotated[list[list[float]], Field(min_length=1)]
    gripper_events: Annotated[list[GripperEventIn], Field(max_length=10_000)] = []


def validation_problem(e: ValidationError, limit: int = 3) -> tuple[str, str]:
    """(key of the first error, every error up to limit as `key: message`) of a pydantic error."""
    errors = e.errors(include_url=False)
    keys = [".".join(str(x) for x in err["loc"]) or "<root>" for err in errors]
    problems = "; ".join(f"{key}: {err['msg']}" for key, err in zip(keys, errors[:limit], strict=False))
    more = f" (and {len(errors) - limit} more)" if len(errors) > limit else ""
    return keys[0], problems + more


def load_trajectory_file(path: Path, joint_names: tuple[str, ...]) -> JointTrajectory:
    try:
        data = load_json(path, "trajectory JSON")
    except InputFileError as e:
        raise InputError(e.file, e.problem, e.key, e.line, e.column) from None
    try:
        raw = TrajectoryFile.model_validate(data)
    except ValidationError as e:
        key, problems = validation_problem(e)
        raise InputError(path, f"invalid trajectory: {problems}", key) from None
    if tuple(raw.joint_names) != joint_names:
        raise InputError(path, f"{raw.joint_names} must be the robot's joints {list(joint_names)}", "joint_names")
    bad_rows = [k for k, row in enumerate(raw.positions) if len(row) != len(joint_names)]
    if bad_rows:
        k = bad_rows[0]
        raise InputError(
            path,
            f"has {len(raw.positions[k])} values, expected {len(joint_names)} ({len(bad_rows)} bad rows)",
            f"positions[{k}]",
        )
    events = tuple(GripperEvent(**ev.model_dump()) for ev in raw.gripper_events)
    return JointTrajectory(tuple(raw.joint_names), raw.dt, np.array(raw.positions, dtype=np.float64), events)


def check_files(config: SafetyConfig, trajectory_path: Path, world_path: Path | None = None) -> GateReport:
    """Validate the trajectory in TRAJ.json against the world in WORLD.json (table only when None)."""
    robot = RobotModel()
    trajectory = load_trajectory_file(trajectory_path, robot.joint_names)
    if world_path is None:
        world = CollisionWorld(robot, config)
    else:
        try:
            desc, points = load_world_file(world_path)
        except WorldFileError as e:
            raise InputError(e.file, e.problem, e.key, e.line, e.column) from None
        world = CollisionWorld.from_description(robot, config, desc, points)
    try:
        return validate(trajectory, world)
    except TrajectoryError as e:
        raise InputError(trajectory_path, str(e), "joint_names") from None
