"""Finding the target again after execution (and at the second look): of several regions its phrase matches, the
only one of its size and colour in the planning capture is the target."""

from __future__ import annotations

import numpy as np

from pipeline.perception.segmenter import Detection, box_of
from runtime.run.verification import find_target_again

PURPLE = (150, 60, 200)


class Regions:
    """A segmenter that answers every phrase with the given masks."""

    def __init__(self, *masks: np.ndarray) -> None:
        self.masks = masks

    def segment(self, rgb: np.ndarray, phrase: str, depth_m: np.ndarray | None = None) -> list[Detection]:
        return [Detection(m, 0.5, box_of(m), "purple") for m in self.masks]


def square(v: int, u: int, side: int) -> np.ndarray:
    m = np.zeros((120, 160), bool)
    m[v : v + side, u : u + side] = True
    return m


def paint(*masks: np.ndarray, colour=PURPLE) -> np.ndarray:
    rgb = np.full((120, 160, 3), 120, np.uint8)
    for m in masks:
        rgb[m] = colour
    return rgb


def test_the_region_of_the_targets_size_and_colour_is_the_target_found_again():
    cube_before, cube_after, bowl = square(20, 20, 12), square(70, 100, 12), square(40, 40, 40)
    before, after = paint(cube_before), paint(cube_after, bowl)
    found = find_target_again(Regions(bowl, cube_after), after, "the purple cube", before, cube_before)
    assert len(found) == 1 and (found[0].mask == cube_after).all()


def test_two_regions_like_the_target_stay_two():
    cube_before = square(20, 20, 12)
    twins = (square(70, 100, 12), square(70, 20, 12))
    found = find_target_again(Regions(*twins), paint(*twins), "the purple cube", paint(cube_before), cube_before)
    assert len(found) == 2  # verification refuses: it cannot tell which one is the target


def test_a_white_can_on_a_scales_white_plate_is_found_among_what_changed(sim_profile_with, tmp_path):
    """The can and the scale's plate are one white region, named by the scale's base: the phrase matches nothing in
    the image as it is; among the pixels that changed since the planning capture, the can stands alone."""
    from drivers.sim import SimCamera, SimWorld
    from pipeline.perception.offline_segmenter import OfflineSegmenter
    from sim_helpers import put_object, write_can_and_scale

    profile = sim_profile_with({"sim": {"scene": write_can_and_scale(tmp_path / "scale.yaml")}})
    world = SimWorld(profile.sim, profile.camera)
    seg = OfflineSegmenter()
    with SimCamera(world, seed=0) as camera:
        before = camera.read()
        (can_before,) = seg.segment(before.rgb, "the white can", before.depth)
        put_object(world, "can", (0.41, -0.01, 0.031 + 0.0295 + 0.002))
        after, truth = camera.read(), camera.object_masks()
    assert seg.segment(after.rgb, "the white can", after.depth) == []  # merged with the plate
    (found,) = find_target_again(seg, after.rgb, "the white can", before.rgb, can_before.mask, after.depth)
    assert (found.mask & truth["can"]).sum() / (found.mask | truth["can"]).sum() > 0.6
