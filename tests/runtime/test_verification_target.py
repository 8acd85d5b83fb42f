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

    def segment(self, rgb: np.ndarray, phrase: str) -> list[Detection]:
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
