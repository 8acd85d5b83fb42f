"""The gate on files: TRAJ.json (+ optional WORLD.json) -> GateReport, for `goalvla check-trajectory`.

TRAJ.json: {"joint_names": [...7 names in robot order], "dt": seconds > 0, "positions": [[7 rad] * N],
            "gripper_events": [{"time_s": t, "kind": "open"|"close"|"wait", "width_m": w, "duration_s": d}]}
(gripper_events optional). Unknown keys, NaN/inf, a missing or non-positive dt, ragged rows or the wrong joints
make the input unusable: InputError, whose message names the file and the problem.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from safety.collision import CollisionWorld
from safety.config import SafetyConfig
from safety.gate import TrajectoryError, validate
from safety.robot_model import RobotModel
from safety.trajectory import GripperEvent, JointTrajectory
from safety.violations import GateReport
from safety.world import WorldFileError, load_world_file


class InputError(ValueError):
    """An input file is unusable; the message names it and the problem."""


class _Input(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class GripperEventIn(_Input):
    time_s: Annotated[float, Field(ge=0)]
    kind: Literal["open", "close", "wait"]
    width_m: Annotated[float, Field(ge=0)] = 0.0
    duration_s: Annotated[float, Field(ge=0)] = 0.0


class TrajectoryFile(_Input):
    joint_names: list[str]
    dt: Annotated[float, Field(gt=0)]
    positions: Annotated[list[list[float]], Field(min_length=1)]
    gripper_events: list[GripperEventIn] = []


def _errors(e: ValidationError, limit: int = 3) -> str:
    return "; ".join(f"{'.'.join(str(x) for x in err['loc']) or '<root>'}: {err['msg']}" for err in e.errors()[:limit])


def load_trajectory_file(path: Path, joint_names: tuple[str, ...]) -> JointTrajectory:
    try:
        raw = TrajectoryFile.model_validate(json.loads(Path(path).read_text()))
    except (OSError, json.JSONDecodeError) as e:
        raise InputError(f"{path}: cannot read trajectory JSON: {e}") from e
    except ValidationError as e:
        raise InputError(f"{path}: invalid trajectory: {_errors(e)}") from e
    if tuple(raw.joint_names) != joint_names:
        raise InputError(f"{path}: joint_names {raw.joint_names} must be the robot's joints {list(joint_names)}")
    bad_rows = [k for k, row in enumerate(raw.positions) if len(row) != len(joint_names)]
    if bad_rows:
        k = bad_rows[0]
        raise InputError(
            f"{path}: positions[{k}] has {len(raw.positions[k])} values, expected {len(joint_names)} "
            f"({len(bad_rows)} bad rows)"
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
            raise InputError(str(e)) from e
        world = CollisionWorld.from_description(robot, config, desc, points)
    try:
        return validate(trajectory, world)
    except TrajectoryError as e:
        raise InputError(f"{trajectory_path}: {e}") from e
