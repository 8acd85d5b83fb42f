"""Fixtures of the reasoning tests (the fake provider server lives in fake_http.py)."""

import pytest
from fake_http import fake_server, scene_rgb

__all__ = ["fake_server", "scene_rgb"]


@pytest.fixture(scope="session")
def sim_view(sim_profile_with):
    """One capture of the default tabletop scene: (frame, ground-truth masks for checking, world)."""
    from drivers.sim import SimCamera, SimWorld

    profile = sim_profile_with()
    world = SimWorld(profile.sim, profile.camera)
    camera = SimCamera(world, seed=0)
    camera.connect()
    frame = camera.read()
    masks = camera.object_masks()
    camera.close()
    return frame, masks, world
