"""The command line: capture writes a geometrically correct frame; bad configs exit 2 with a readable error."""

import subprocess
import sys

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from runtime.commands.cli import app

runner = CliRunner()


def test_help_lists_commands_and_starts_fast():
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "runtime.commands.cli", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0 and "capture" in done.stdout and "demo" in done.stdout
    heavy = [m for m in ("mujoco", "torch", "pinocchio", "open3d") if f" {m}\n" in done.stderr]
    assert heavy == [], f"--help imported {heavy}"


def test_capture_writes_a_correct_frame(tmp_path, sim_config_path):
    result = runner.invoke(app, ["capture", "--config", str(sim_config_path), "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    data = np.load(tmp_path / "frame.npz")
    rgb, depth, K, T = data["rgb"], data["depth"], data["K"], data["T_base_camera"]
    assert rgb.dtype == np.uint8 and depth.dtype == np.float32 and rgb.shape[:2] == depth.shape
    assert np.isfinite(T).all() and np.isnan(depth).any()
    # the table top (z = 0 in the base frame) is where the depth says it is
    v, u = np.mgrid[0 : depth.shape[0], 0 : depth.shape[1]]
    pts = np.stack([(u - K[0, 2]) / K[0, 0] * depth, (v - K[1, 2]) / K[1, 1] * depth, depth], -1).reshape(-1, 3)
    z_base = (pts @ T[:3, :3].T + T[:3, 3])[:, 2]
    z_base = z_base[np.isfinite(z_base)]
    table = np.abs(z_base) < 0.02
    assert table.mean() > 0.5
    assert abs(np.median(z_base[table])) < 0.001
    assert cv2.imread(str(tmp_path / "rgb.png")).shape == rgb.shape
    assert cv2.imread(str(tmp_path / "depth.png")).shape == rgb.shape


def test_invalid_config_exits_2_with_the_key(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("robot:\n  kind: xarm7\n  bogus: true\n")
    result = runner.invoke(app, ["capture", "--config", str(bad), "--out", str(tmp_path)])
    assert result.exit_code == 2
    assert "robot.bogus: unknown key" in result.output


@pytest.mark.slow
def test_demo_moves_the_arm_and_saves_captures(tmp_path, sim_config_path):
    result = runner.invoke(app, ["demo", "--config", str(sim_config_path), "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    folders = sorted(p.name for p in tmp_path.iterdir())
    assert folders == ["00_left", "01_forward", "02_right", "03_home"]
    rgbs = [cv2.imread(str(tmp_path / f / "rgb.png")) for f in folders]
    assert np.abs(rgbs[0].astype(int) - rgbs[2].astype(int)).mean() > 1.0  # the arm really moved
