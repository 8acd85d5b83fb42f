"""The object a part belongs to, of several regions its phrase matches: the one the part is attached to."""

from __future__ import annotations

import numpy as np

from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.perception.segmenter import Detection, attached_to, box_of
from sim_helpers import write_scene


def _region(v0: int, v1: int, u0: int, u1: int) -> Detection:
    m = np.zeros((100, 120), bool)
    m[v0:v1, u0:u1] = True
    return Detection(m, 1.0, box_of(m), "pink lidded box")


def test_the_region_holding_or_bordering_the_part_most_is_its_object():
    lid = _region(20, 40, 40, 80).mask
    chest = _region(20, 70, 40, 80)  # holds the lid (a lid of its own colour)
    behind = _region(5, 21, 50, 70)  # touches part of the lid's top edge
    (found,) = attached_to([behind, chest], lid)
    assert found is chest
    body = _region(40, 70, 40, 80)  # a lid of another colour: the chest's body borders it along the hinge
    (found,) = attached_to([behind, body], lid)
    assert found is body
    apart = [_region(80, 95, 0, 20), _region(80, 95, 100, 120)]
    assert attached_to(apart, lid) == apart  # none touches it: still two, and the caller refuses


def test_close_the_chest_takes_the_chest_whose_lid_it_is_not_a_bowl_behind_it(sim_profile_with, tmp_path):
    """A bowl half hidden behind the open chest reads as a chest too; the chest is the one the lid is part of."""
    from drivers.sim import SimCamera, SimWorld

    chest = {"name": "chest", "kind": "lidded_box", "size_m": [0.104, 0.124, 0.051], "color": "pink"}
    chest |= {"xy_m": [0.5306, -0.1254], "yaw_deg": -20.76, "lid_open_deg": 87.2}
    bowl = {"name": "bowl", "kind": "bowl", "color": "light_cyan", "radius_m": 0.065, "height_m": 0.053}
    bowl |= {"xy_m": [0.2955, -0.1525], "yaw_deg": -40.6}
    path = write_scene(tmp_path / "behind.yaml", [chest, bowl])
    profile = sim_profile_with({"sim": {"scene": str(path)}})
    with SimCamera(SimWorld(profile.sim, profile.camera), seed=0) as camera:
        frame, truth = camera.read(), camera.object_masks()
    seg = OfflineSegmenter()
    chests = seg.segment(frame.rgb, "the chest", frame.depth)
    assert len(chests) == 2  # the premise: the bowl's visible part reads as a chest
    (lid,) = seg.segment(frame.rgb, "the lid of the chest", frame.depth)
    (found,) = attached_to(chests, lid.mask)
    assert (found.mask & truth["chest"]).sum() > 0.8 * found.area_px
