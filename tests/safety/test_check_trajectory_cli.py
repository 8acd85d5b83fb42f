"""`goalvla check-trajectory`: JSON report on stdout; exit 0 valid, 3 violations, 2 unusable input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from trajectories import NAMES, min_jerk
from typer.testing import CliRunner

from runtime.commands.cli import app
from safety.robot_model import RobotModel

runner = CliRunner()
HOME = RobotModel().home_q


def _write(tmp_path, name: str, content) -> str:
    path = tmp_path / name
    path.write_text(content if isinstance(content, str) else json.dumps(content))
    return str(path)


def _traj(positions, dt=0.004, **extra) -> dict:
    return {"joint_names": list(NAMES), "dt": dt, "positions": np.asarray(positions).tolist(), **extra}


def _run(sim_config_path, traj_path, world_path=None):
    args = ["check-trajectory", "--config", str(sim_config_path), "--trajectory", traj_path]
    if world_path:
        args += ["--world", world_path]
    return runner.invoke(app, args)


def test_valid_trajectory_exits_0(tmp_path, sim_config_path):
    traj = _write(tmp_path, "t.json", _traj(min_jerk(HOME, HOME + 0.2, 1.0)))
    result = _run(sim_config_path, traj)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["ok"] is True and report["violations"] == []


def test_violations_exit_3_with_time_kind_detail(tmp_path, sim_config_path):
    q = np.tile(HOME, (20, 1))
    q[10:, 0] += 0.05  # one jump per tick above 0.04 rad
    tcp = RobotModel().tcp_pose(HOME)[:3, 3]
    world = _write(
        tmp_path,
        "w.json",
        {"boxes": [{"name": "crate", "center": (tcp + np.array([0, 0, 0.1])).tolist(), "size": [0.1, 0.1, 0.05]}]},
    )
    result = _run(sim_config_path, _write(tmp_path, "t.json", _traj(q)), world)
    assert result.exit_code == 3, result.output
    report = json.loads(result.stdout)
    assert report["ok"] is False
    kinds = {v["kind"] for v in report["violations"]}
    assert {"step", "collision"} <= kinds
    step = next(v for v in report["violations"] if v["kind"] == "step")
    assert step["time"] == pytest.approx(0.04) and "joint1" in step["detail"]
    assert all({"time", "kind", "detail"} <= set(v) for v in report["violations"])


def test_world_with_point_cloud_file(tmp_path, sim_config_path):
    tcp = RobotModel().tcp_pose(HOME)[:3, 3]
    np.savez(
        tmp_path / "cloud.npz",
        points=tcp + np.array([0, 0, 0.1]) + np.random.default_rng(0).uniform(-0.02, 0.02, (200, 3)),
    )
    world = _write(tmp_path, "w.json", {"points_file": "cloud.npz"})
    result = _run(sim_config_path, _write(tmp_path, "t.json", _traj(np.tile(HOME, (5, 1)))), world)
    assert result.exit_code == 3
    assert any("point_cloud" in v["detail"] for v in json.loads(result.stdout)["violations"])


UNUSABLE = {
    "wrong joint count": (_traj(np.zeros((3, 6))), "positions[0]: has 6 values"),
    "wrong joint names": ({**_traj(np.zeros((3, 7))), "joint_names": [f"j{i}" for i in range(7)]}, "joint_names"),
    "missing dt": ({k: v for k, v in _traj(np.zeros((3, 7))).items() if k != "dt"}, "dt"),
    "zero dt": (_traj(np.zeros((3, 7)), dt=0.0), "dt"),
    "negative dt": (_traj(np.zeros((3, 7)), dt=-0.004), "dt"),
    "unknown key": (_traj(np.zeros((3, 7)), speed=1.0), "speed"),
    "empty positions": (_traj(np.zeros((0, 7))), "positions"),
    "not json": ("{ positions: ", "cannot read trajectory JSON"),
}


@pytest.mark.parametrize("case", list(UNUSABLE))
def test_unusable_trajectory_exits_2(tmp_path, sim_config_path, case):
    content, needle = UNUSABLE[case]
    result = _run(sim_config_path, _write(tmp_path, "t.json", content))
    assert result.exit_code == 2, result.output
    assert "t.json" in result.output and needle in result.output


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_non_finite_positions_exit_2(tmp_path, sim_config_path, literal):
    rows = ", ".join(["[0, 0, 0, 0, 0, 0, 0]"] * 2 + [f"[0, 0, {literal}, 0, 0, 0, 0]"])
    text = f'{{"joint_names": {json.dumps(list(NAMES))}, "dt": 0.004, "positions": [{rows}]}}'
    result = _run(sim_config_path, _write(tmp_path, "t.json", text))
    assert result.exit_code == 2 and "positions.2.2" in result.output


@pytest.mark.parametrize(
    "world,needle",
    [
        ({"boxes": [{"center": [0, 0, 0], "size": [0.1, -0.1, 0.1]}]}, "boxes.0.size"),
        ({"boxes": [{"center": [0, 0], "size": [0.1, 0.1, 0.1]}]}, "boxes.0.center"),
        ({"spheres": [{"center": [0, 0, 0], "radius": 0.1, "color": "red"}]}, "color"),
        ({"planes": []}, "planes"),
        ({"points_file": "missing.npz"}, "missing.npz"),
        ("[1, 2", "cannot read world JSON"),
    ],
)
def test_malformed_world_exits_2(tmp_path, sim_config_path, world, needle):
    traj = _write(tmp_path, "t.json", _traj(np.tile(HOME, (3, 1))))
    result = _run(sim_config_path, traj, _write(tmp_path, "w.json", world))
    assert result.exit_code == 2, result.output
    assert "w.json" in result.output and needle in result.output
