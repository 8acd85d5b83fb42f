"""`goalvla ground`: RESULT.json on a simulated pair, exit 2 naming the key on bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from grounding_helpers import goal_pose
from typer.testing import CliRunner

from runtime.commands.cli import app


@pytest.fixture(scope="module")
def pair(pair_renderer):
    goal = goal_pose(pair_renderer, "box_b", (-0.10, 0.05), 60.0)
    return pair_renderer.render("box_b", goal, "depth", np.random.default_rng(5))


def _write(path, arrays):
    np.savez(path, **arrays)
    return path


def test_ground_writes_the_motion(tmp_path, pair, sim_config_path):
    pair_file = _write(tmp_path / "pair.npz", pair.as_npz_dict())
    out = tmp_path / "result.json"
    result = CliRunner().invoke(
        app, ["ground", "--config", str(sim_config_path), "--scene-file", str(pair_file), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["ok"] and data["reason"] == ""
    R, t = np.array(data["R"]), np.array(data["t"])
    M, c = pair.T_motion_camera, pair.centre_camera
    assert np.linalg.norm((R @ c + t) - (M[:3, :3] @ c + M[:3, 3])) < 0.006
    assert set(data) >= {"ok", "reason", "R", "t", "scale", "inliers", "residual_m"}


def _small_pair() -> dict:
    rng = np.random.default_rng(0)
    mask = np.zeros((24, 32), bool)
    mask[8:16, 10:20] = True
    return {
        "rgb0": rng.integers(0, 255, (24, 32, 3), dtype=np.uint8),
        "depth0": np.full((24, 32), 1.0, np.float32),
        "mask0": mask,
        "rgb1": rng.integers(0, 255, (24, 32, 3), dtype=np.uint8),
        "depth1": np.full((24, 32), 0.5, np.float32),
        "depth1_kind": np.array("disparity"),
        "mask1": mask,
        "K": np.array([[30.0, 0, 15.5], [0, 30.0, 11.5], [0, 0, 1]]),
    }


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda d: d.pop("mask1"), "mask1"),
        (lambda d: d.update(depth0=d["depth0"].astype(np.int32)), "depth0"),
        (lambda d: d.update(rgb1=d["rgb1"][:, :-1]), "rgb1"),
        (lambda d: d.update(mask0=np.zeros((24, 32), bool)), "mask0"),
        (lambda d: d.update(depth1=np.full((24, 32), np.nan, np.float32)), "depth1"),
        (lambda d: d.update(depth0=np.zeros((24, 32), np.float32)), "depth0"),
        (lambda d: d.update(depth1_kind=np.array("inverse")), "depth1_kind"),
        (lambda d: d.update(K=np.eye(2)), "K"),
        (lambda d: d.update(mask1=d["mask1"].astype(np.uint8)), "mask1"),
        (lambda d: d.update(anchor0=d["mask0"][:, :-1]), "anchor0"),
        (lambda d: d.update(anchor0=np.zeros((24, 32), bool)), "anchor0"),
    ],
)
def test_bad_input_exits_2_naming_the_key(tmp_path, change, key, sim_config_path):
    arrays = _small_pair()
    change(arrays)
    pair_file = _write(tmp_path / "pair.npz", arrays)
    out = tmp_path / "result.json"
    result = CliRunner().invoke(
        app, ["ground", "--config", str(sim_config_path), "--scene-file", str(pair_file), "--out", str(out)]
    )
    assert result.exit_code == 2
    assert key in result.output
    assert not out.exists()


def test_refusal_writes_ok_false_with_reason(tmp_path, sim_config_path):
    arrays = _small_pair()  # constant goal prediction: nothing to align
    pair_file = _write(tmp_path / "pair.npz", arrays)
    out = tmp_path / "result.json"
    result = CliRunner().invoke(
        app, ["ground", "--config", str(sim_config_path), "--scene-file", str(pair_file), "--out", str(out)]
    )
    assert result.exit_code == 1
    data = json.loads(out.read_text())
    assert data["ok"] is False and "constant" in data["reason"]
