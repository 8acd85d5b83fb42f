"""A push with no room for the hand behind the object: a neighbour stands closer behind it than the closed fingers,
the standoff and the gate's padding need. The run carries the object to where the push would have left it (the
profile allows it by default) and says why; with the carry switched off it refuses, naming the push's rejections.
Nothing else is touched: the neighbour stays where it was."""

from __future__ import annotations

import numpy as np
import pytest
from runtime_helpers import free_port

from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.run.runner import Runtime
from runtime.run.stages import PipelineStages
from runtime.sim_truth.listener import SimTruth
from runtime.supervision.states import State

pytestmark = pytest.mark.slow
SHIFT_M = 0.06  # "right" in the camera's image is +y in the base frame (the camera looks back at the robot)
# the block's back face at y = -0.025; the neighbour's front face 35 mm behind it
SCENE = """name: crowded_push
objects:
  - {name: red_block, kind: box, size_m: [0.05, 0.05, 0.05], color: red, xy_m: [0.42, 0.0]}
  - {name: blue_box, kind: box, size_m: [0.06, 0.07, 0.09], color: blue, xy_m: [0.42, -0.095]}
randomise: {xy_jitter_m: 0.0, yaw_jitter_deg: 0.0}
"""


def _run(sim_config_path, tmp_path, carry: bool):
    scene = tmp_path / "crowded_push.yaml"
    scene.write_text(SCENE)
    overrides = {
        "sim": {"seed": 0, "scene": str(scene)},
        "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}},
        "pipeline": {"contact": {"carry_when_no_push": carry}},
    }
    profile = load_profile(sim_config_path, overrides)
    stages = PipelineStages(listeners=[SimTruth()])
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as rt:
        block0 = devices.world.object_pose("red_block")[:3, 3]
        neighbour0 = devices.world.object_pose("blue_box")[:3, 3]
        result = rt.run(f"push the red block right by {SHIFT_M * 100:.0f} cm", tmp_path / "run")
        block = devices.world.object_pose("red_block")[:3, 3]
        neighbour = devices.world.object_pose("blue_box")[:3, 3]
    return result, block - block0, neighbour - neighbour0


def test_a_push_with_no_room_behind_is_carried_to_where_it_would_end(sim_config_path, tmp_path):
    result, moved, neighbour_moved = _run(sim_config_path, tmp_path, carry=True)
    assert result.status == State.DONE, result.reason
    contact = result.summary.contact
    assert contact.mode == "grasp"
    assert contact.carried_because.startswith("no feasible push: all ") and "gripper hits the scene" in (
        contact.carried_because
    )
    assert "carried instead of pushed" in (tmp_path / "run" / "report.html").read_text()
    np.testing.assert_allclose(moved[:2], [0.0, SHIFT_M], atol=0.02)
    assert np.linalg.norm(neighbour_moved) < 0.005


def test_with_the_carry_switched_off_the_crowded_push_is_refused(sim_config_path, tmp_path):
    result, moved, _ = _run(sim_config_path, tmp_path, carry=False)
    assert result.status == State.FAILED
    assert "no feasible push: all " in result.reason and "carry" not in result.reason
    assert result.summary.contact.mode == "push" and result.summary.contact.carried_because is None
    assert result.summary.execution == []
    assert np.linalg.norm(moved) < 0.005
