"""Shared fixtures: profiles and simulated worlds built from the repository's own configs."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"
sys.path.insert(0, str(Path(__file__).parent))  # tests/sim_helpers.py


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
