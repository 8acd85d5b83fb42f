"""Shared fixtures: profiles and simulated worlds built from the repository's own configs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"
sys.path.insert(0, str(Path(__file__).parent))  # tests/sim_helpers.py, tests/console_client.py


@pytest.fixture(scope="session")
def sim_config_path() -> Path:
    return CONFIGS / "sim.yaml"


@pytest.fixture(scope="session")
def sim_profile_with():
    """Factory: the default sim profile with overrides; physics stepped by the test unless realtime is set."""
    from runtime.config import load_profile

    def make(overrides: dict | None = None):
        overrides = dict(overrides or {})
        overrides["sim"] = {"realtime": False, **overrides.get("sim", {})}
        return load_profile(CONFIGS / "sim.yaml", overrides)

    return make


@pytest.fixture
def stepped_profile(sim_config_path):
    """The default sim profile with physics advanced only by world.step() (deterministic)."""
    from runtime.config import load_profile

    return load_profile(sim_config_path, {"sim": {"realtime": False}})


@pytest.fixture(scope="session")
def lid_views(sim_profile_with):
    """The close_lid scene seen with the lid open, then shut: (open frame, shut frame, lid mask open, lid mask shut,
    box mask open, true lid motion T_camera (x_shut = T x_open)); frames carry T_base_camera."""
    import math

    from drivers.sim import SimCamera, SimWorld
    from sim_helpers import body_pose, set_hinge

    profile = sim_profile_with({"sim": {"scene": "close_lid", "seed": 0}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=0) as camera:
        T_base_camera = camera.T_base_camera
        open_frame = camera.read().with_extrinsics(T_base_camera)
        lid_open, box_open, T_lid_open = (
            camera.body_mask("box_lid"),
            camera.body_mask("box"),
            body_pose(world, "box_lid"),
        )
        set_hinge(world, "box_hinge", math.radians(0.5))
        shut_frame = camera.read().with_extrinsics(T_base_camera)
        lid_shut, T_lid_shut = camera.body_mask("box_lid"), body_pose(world, "box_lid")
    T_motion = np.linalg.inv(T_base_camera) @ T_lid_shut @ np.linalg.inv(T_lid_open) @ T_base_camera
    return open_frame, shut_frame, lid_open, lid_shut, box_open, T_motion
