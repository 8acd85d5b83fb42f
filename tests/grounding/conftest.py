"""A simulated grounding world shared by the tests of this folder (built once: rendering is the slow part)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="package")
def pair_renderer(sim_profile_with):
    from drivers.sim import SimWorld
    from pipeline.grounding.sim_pairs import PairRenderer

    profile = sim_profile_with({"sim": {"scene": "grounding_bench"}})
    renderer = PairRenderer(SimWorld(profile.sim, profile.camera))
    yield renderer
    renderer.close()
