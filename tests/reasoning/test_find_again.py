"""A target found again in a later image when its phrase names nothing there: a lid of another colour, shut over
its chest, hides the chest's top; what is left of the chest reads as another kind, and the lid is found by its own
colour in the first image. A lid of its chest's own colour is not looked for that way (every piece of the chest
would be of that colour)."""

from __future__ import annotations

import math

from pipeline.perception.offline_segmenter import OfflineSegmenter
from pipeline.reasoning.checks import find_again
from sim_helpers import set_hinge, write_scene


def _open_and_shut(sim_profile_with, tmp_path, lid_color: str | None, chest: dict | None = None, others=()):
    from drivers.sim import SimCamera, SimWorld

    chest = chest or {"size_m": [0.127, 0.165, 0.07], "color": "light_pink", "xy_m": [0.5142, 0.0935]} | {
        "yaw_deg": -20.4,
        "lid_open_deg": 101.9,
    }
    chest = {"name": "chest", "kind": "lidded_box"} | chest | ({"lid_color": lid_color} if lid_color else {})
    path = write_scene(tmp_path / "chest.yaml", [chest, *others])
    profile = sim_profile_with({"sim": {"scene": str(path)}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=0) as camera:
        opened, lid_open, box = camera.read(), camera.body_mask("chest_lid"), camera.object_masks()["chest"]
        set_hinge(world, "chest_hinge", math.radians(0.5))
        shut, lid_shut = camera.read(), camera.body_mask("chest_lid")
    return opened, lid_open, box & ~lid_open, shut, lid_shut


def test_a_shut_lid_of_another_colour_is_found_by_its_colour(sim_profile_with, tmp_path):
    opened, lid_open, box, shut, lid_shut = _open_and_shut(sim_profile_with, tmp_path, "dark_blue")
    seg = OfflineSegmenter()
    (lid,) = seg.segment(opened.rgb, "the lid of the chest", opened.depth)
    assert (lid.mask & lid_open).sum() > 0.8 * lid.area_px
    (found,), _how = find_again(seg, shut.rgb, "the lid of the chest", opened.rgb, lid.mask, shut.depth, box)
    assert (found.mask & lid_shut).sum() / (found.mask | lid_shut).sum() > 0.6
    # by its colour alone: a phrase that names nothing in the shut view, nor among the pixels that changed
    phrase = "the lid of the bottle"
    assert find_again(seg, shut.rgb, phrase, opened.rgb, lid.mask, shut.depth) == ([], "")  # no anchor: no colour
    (found,), how = find_again(seg, shut.rgb, phrase, opened.rgb, lid.mask, shut.depth, mask_anchor=box)
    assert how == "by its own colour, blue"
    assert (found.mask & lid_shut).sum() / (found.mask | lid_shut).sum() > 0.6


def test_a_lid_of_its_chests_colour_is_not_looked_for_by_that_colour(sim_profile_with, tmp_path):
    opened, _lid_open, box, shut, _lid_shut = _open_and_shut(sim_profile_with, tmp_path, "light_pink")
    seg = OfflineSegmenter()
    (lid,) = seg.segment(opened.rgb, "the lid of the light pink chest", opened.depth)
    # a phrase that names nothing shut: by the lid's colour, every pink piece of the chest would come back
    assert seg.segment(shut.rgb, "pink", shut.depth) != []
    found, how = find_again(seg, shut.rgb, "the lid of the bottle", opened.rgb, lid.mask, shut.depth, box)
    assert found == [] and how == ""


def test_a_turned_chests_lid_is_found_open_and_shut_on_its_chest_not_elsewhere(sim_profile_with, tmp_path):
    """Generated case 12104: the chest turned 33 deg, its light red lid open 84 deg shows a side edge rising from
    the hinge over a quarter of its width, which rests on nothing: the depth image shows lid and chest meet. Shut,
    the chest reads as a red block on pink sides, and a small pink block elsewhere as 'the chest': its lid there is
    no part of this chest, which stays where it was."""
    chest = {"size_m": [0.126, 0.128, 0.058], "color": "pink", "xy_m": [0.5207, 0.3037], "yaw_deg": 33.35}
    chest["lid_open_deg"] = 83.6
    block = {"name": "block", "kind": "box", "size_m": [0.036, 0.042, 0.032], "color": "dark_pink"}
    block |= {"xy_m": [0.2906, 0.1011], "yaw_deg": -52.4}
    opened, lid_open, box, shut, lid_shut = _open_and_shut(sim_profile_with, tmp_path, "light_red", chest, [block])
    seg = OfflineSegmenter()
    (lid,) = seg.segment(opened.rgb, "the lid of the chest", opened.depth)
    assert (lid.mask & lid_open).sum() > 0.8 * lid.area_px
    # as an edited goal is checked: no depth
    (found,), _how = find_again(seg, shut.rgb, "the lid of the chest", opened.rgb, lid.mask, mask_anchor=box)
    assert (found.mask & lid_shut).sum() / (found.mask | lid_shut).sum() > 0.6


def test_a_part_is_found_again_only_on_its_object():
    """A region the phrase names away from the part's object (another thing read as the chest) is not the part:
    the search goes on, here to the part's own colour next to its object."""
    import numpy as np

    from pipeline.perception.segmenter import Detection, box_of

    def region(u0: int, v0: int, u1: int, v1: int) -> np.ndarray:
        mask = np.zeros((60, 80), bool)
        mask[v0:v1, u0:u1] = True
        return mask

    chest, far, near = region(40, 30, 70, 50), region(2, 2, 10, 10), region(40, 20, 70, 30)
    rgb = np.zeros((60, 80, 3), np.uint8)

    class Stub:
        def segment(self, image, phrase, depth_m=None):
            mask = far if phrase.startswith("the lid") else near
            return [Detection(mask, 1.0, box_of(mask), phrase)]

        def colours_of(self, image, *masks):
            return ("red", "pink")

    found, how = find_again(Stub(), rgb, "the lid of the chest", rgb, near, mask_anchor=chest)
    assert [d.label for d in found] == ["red"] and how == "by its own colour, red"
    assert find_again(Stub(), rgb, "the lid of the chest", rgb, near)[0][0].label == "the lid of the chest"
