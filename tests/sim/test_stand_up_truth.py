"""The simulator's truth of a stand-up: a bottle stands only the right way up (its neck end up); lying, or on its
neck, it is not stood up, whatever the grounded goal motion said."""

from __future__ import annotations

import pytest
from scipy.spatial.transform import Rotation


def _turn_bottle(world, name: str, neck_up: float) -> None:
    """Turn the bottle about its centre so its body-to-neck axis points along (0, 0, neck_up)."""
    from drivers.sim.gl import mujoco

    m, d = world.model, world.data
    axis = d.geom(f"{name}_g0").xmat.reshape(3, 3)[:, 2]
    turn, _ = Rotation.align_vectors([[0.0, 0.0, neck_up]], [axis])
    adr = m.jnt_qposadr[m.joint(f"{name}_free").id]
    root = Rotation.from_quat(d.qpos[adr + 3 : adr + 7], scalar_first=True)
    d.qpos[adr + 3 : adr + 7] = (turn * root).as_quat(scalar_first=True)
    d.qpos[adr + 2] += 0.15  # clear of the table whichever way it stands
    mujoco.mj_forward(m, d)


@pytest.mark.parametrize(("neck_up", "stood"), [(None, False), (1.0, True), (-1.0, False)])
def test_a_bottle_is_stood_up_only_neck_end_up(sim_profile_with, neck_up, stood):
    from drivers.sim import SimWorld
    from pipeline.reasoning.instruction import parse_instruction
    from runtime.sim_truth.tasks import task_truth

    profile = sim_profile_with({"sim": {"scene": "bottle_standup", "seed": 0}})
    world = SimWorld(profile.sim, profile.camera)
    name = next(o.name for o in world.scene.objects if o.kind == "bottle")
    if neck_up is not None:
        _turn_bottle(world, name, neck_up)
    truth = task_truth(world, parse_instruction("stand the green bottle up"))
    assert truth.action == "stand_up" and truth.done is stood, truth.detail
    assert ("neck end 0 deg" in truth.detail) is (neck_up == 1.0)
