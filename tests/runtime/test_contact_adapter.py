"""The contact stage's hand-over to the manipulation chain: the held object's box, and a whole stand-up run whose
grounded turn about the bottle's own axis would have ended with the wrist behind the bottle."""

from __future__ import annotations

import numpy as np
import pytest
from runtime_helpers import sim_run_profile

from runtime.contact_adapter import held_box
from runtime.devices import open_devices
from runtime.runner import Runtime
from runtime.stages import PipelineStages
from runtime.states import State


def test_held_box_is_mirrored_across_the_closing_axis_only():
    # the seen top and front of a 0.18 m long, 0.06 m wide bar, grasped from above 0.05 m off its middle
    rng = np.random.default_rng(0)
    points = rng.uniform([-0.09, -0.03, 0.0], [0.09, 0.01, 0.06], (500, 3)) + np.array([0.45, 0.0, 0.0])
    T_base_tcp = np.diag([1.0, -1.0, -1.0, 1.0])  # pointing down, pads along base x, closing along base y
    T_base_tcp[:3, 3] = (0.50, -0.01, 0.03)
    box = held_box(points, T_base_tcp, "link_tcp", "bar")
    size, centre = np.asarray(box.size), box.T_link_geom[:3, 3]
    assert size[0] == pytest.approx(0.18, abs=0.002)  # along the pads: the seen length, no phantom end
    assert centre[0] == pytest.approx(-0.05, abs=0.002)
    assert size[1] == pytest.approx(0.04, abs=0.002)  # across: the farther seen side mirrored about the TCP
    assert centre[1] == 0.0
    assert size[2] == pytest.approx(0.06, abs=0.002)


@pytest.mark.slow
def test_goalvla_run_stands_the_bottle_up(sim_config_path, tmp_path):
    profile = sim_run_profile(sim_config_path, "bottle_standup", 106, "bottle_standup")
    with open_devices(profile) as devices, Runtime(profile, devices, PipelineStages(), confirm="yes") as rt:
        lying = devices.world.object_pose("bottle_shape")[:3, 2]  # the bottle's axis (the shape's own z)
        result = rt.run("stand the green bottle up", tmp_path / "run")
        axis = devices.world.object_pose("bottle_shape")[:3, 2]
    assert abs(lying[2]) < 0.1
    assert result.status == State.DONE, result.reason
    assert result.summary["plan"]["mode"] == "grasp"
    # as grounded, every grasp would end with the wrist behind the bottle: it is set down turned about its axis
    assert min(result.summary["contact"]["turn_from_grounded_deg"]) > 10.0
    assert abs(axis[2]) > np.cos(np.radians(15.0)), f"ground truth: the bottle's axis is {axis}, not upright"
