"""The contact stage in a whole run: a stand-up, planned with the bottle's turns about its own axis as alternatives
(a body of revolution looks the same turned about its axis, so any of them reaches the goal)."""

from __future__ import annotations

import numpy as np
import pytest
from runtime_helpers import sim_run_profile

from runtime.devices import open_devices
from runtime.run.runner import Runtime
from runtime.run.stages import PipelineStages
from runtime.supervision.states import State


@pytest.mark.slow
def test_goalvla_run_stands_the_bottle_up(sim_config_path, tmp_path):
    profile = sim_run_profile(sim_config_path, "bottle_standup", 106, "bottle_standup")
    with open_devices(profile) as devices, Runtime(profile, devices, PipelineStages(), confirm="yes") as rt:
        lying = devices.world.object_pose("bottle_shape")[:3, 2]  # the bottle's axis (the shape's own z)
        result = rt.run("stand the green bottle up", tmp_path / "run")
        axis = devices.world.object_pose("bottle_shape")[:3, 2]
    assert abs(lying[2]) < 0.1
    assert result.status == State.DONE, result.reason
    assert result.summary.plan.mode == "grasp"
    # turned plans among the alternatives (which plan leads depends on which wrists the IK reaches)
    turns = result.summary.contact.turn_from_grounded_deg
    assert len(turns) == result.summary.contact.plans and max(turns) > 10.0, turns
    assert abs(axis[2]) > np.cos(np.radians(15.0)), f"ground truth: the bottle's axis is {axis}, not upright"
