"""Closing a hinged lid: "close" asks for the hinge (arc push) contact, and a whole run on the sim with every
real stage closes the close_lid scene's lid and verifies it."""

from __future__ import annotations

import math

import pytest
from runtime_helpers import sim_run_profile

from runtime.devices import open_devices
from runtime.run.contact import contact_mode
from runtime.run.runner import Runtime
from runtime.run.stages import PipelineStages
from runtime.sim_truth.listener import SimTruth
from runtime.supervision.states import State


@pytest.mark.parametrize(
    ("instruction", "mode"),
    [
        ("close the blue box", "hinge"),
        ("push the red box left", "push"),
        ("put the red block on the white plate", "grasp"),
        ("tidy up, please", "grasp"),  # free text: a grasp
    ],
)
def test_the_instruction_picks_the_contact_mode(instruction, mode):
    assert contact_mode(instruction) == mode


@pytest.mark.slow
def test_goalvla_run_closes_the_lid(sim_config_path, tmp_path):
    profile = sim_run_profile(sim_config_path, "close_lid", 100, "close_lid")
    stages = PipelineStages(listeners=[SimTruth()])
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as rt:
        world = devices.world
        box = world.object_pose("box")
        result = rt.run("close the blue box", tmp_path / "run")
        with world.lock:
            lid_deg = math.degrees(world.data.qpos[world.model.joint("box_hinge").qposadr[0]])
        moved = world.object_pose("box")[:3, 3] - box[:3, 3]
    assert result.status == State.DONE, result.reason
    assert result.summary.plan.mode == "hinge"
    assert result.summary.planning.contact_used.startswith("pipeline.contact #")
    assert [e.status for e in result.summary.execution] == ["completed"] * 3
    assert lid_deg < 15.0, f"ground truth: the lid is still open {lid_deg:.0f} deg"
    assert max(abs(moved)) < 0.01  # the box itself stayed where it was
    truth = result.summary.sim_truth  # the record's truth of a hinged part is its angle, not a centre's miss
    assert truth.hinge_deg["box_hinge"] == pytest.approx(lid_deg, abs=2.0) and truth.target_goal_error_m is None
