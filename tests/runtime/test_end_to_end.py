"""Whole runs on the sim through the real stages: reasoning (offline backends), grounding, the manipulation
chain, the gate, the executor and verification, with the runtime's supervision and record around them.

One run takes the contact decision from runtime.sim_truth.oracle (a top-down grasp of the target at the simulator's
pose of it), so that everything downstream of contact (goal pose = grounded motion applied to the grasp, planning,
gate, execution, verification by re-grounding) is tested on its own; another runs every real stage, pipeline.contact
included."""

from __future__ import annotations

import json

import numpy as np
import pytest
from runtime_helpers import sim_run_profile

from runtime.devices import open_devices
from runtime.run.runner import Runtime
from runtime.run.stages import PipelineStages
from runtime.sim_truth.listener import SimTruth
from runtime.sim_truth.oracle import GroundTruthGraspStages
from runtime.supervision.states import State

pytestmark = pytest.mark.slow


def test_put_the_red_block_on_the_plate(sim_config_path, tmp_path):
    profile = sim_run_profile(sim_config_path, "tabletop", 3)
    stages = GroundTruthGraspStages(listeners=[SimTruth()])
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as rt:
        result = rt.run("put the red block on the white plate", tmp_path / "run")
        plate = devices.world.object_pose("white_plate")[:3, 3]
        block = devices.world.object_pose("red_block")[:3, 3]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert result.status == State.DONE, result.reason
    assert summary["verification"]["ok"] and summary["verification"]["comparison"]["position_error_m"] < 0.03
    assert np.linalg.norm(block[:2] - plate[:2]) < 0.06  # ground truth: the block sits on the plate
    assert summary["plan"]["mode"] == "grasp" and [e["status"] for e in summary["execution"]] == ["completed"] * 5
    assert summary["sim_truth"]["target"] == "red_block" and summary["sim_truth"]["target_goal_error_m"] < 0.03
    for name in ("capture", "goal", "overlay", "masks", "plan", "after"):
        assert (tmp_path / "run" / f"{name}.png").exists(), name


def test_goalvla_run_with_every_real_stage(sim_config_path, tmp_path):
    profile = sim_run_profile(sim_config_path, "tabletop", 0)
    stages = PipelineStages(listeners=[SimTruth()])
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as rt:
        result = rt.run("put the red block on the white plate", tmp_path / "run")
        plate = devices.world.object_pose("white_plate")[:3, 3]
        block = devices.world.object_pose("red_block")[:3, 3]
    assert result.status == State.DONE, result.reason
    assert result.summary.planning.contact_used.startswith("pipeline.contact #")
    assert np.linalg.norm(block[:2] - plate[:2]) < 0.06
    truth = result.summary.sim_truth  # the record's ground truth names the moved object and its real miss
    assert truth.target == "red_block" and truth.target_goal_error_m < 0.03


def test_a_ball_is_verified_by_its_centre_alone(sim_config_path, tmp_path):
    """A ball shows no turn, so verification compares its fitted centre before and after, no registration."""
    profile = sim_run_profile(sim_config_path, "tomato_pan", 118)
    stages = PipelineStages(listeners=[SimTruth()])
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as rt:
        result = rt.run("put the red ball in the pan", tmp_path / "run")
    assert result.status == State.DONE, result.reason
    assert result.summary.verification.comparison.symmetry == "ball"
    assert (
        result.summary.achieved_motion.method == "ball_centre" and result.summary.achieved_motion.registration is None
    )
    assert result.summary.sim_truth.target_goal_error_m < 0.03
