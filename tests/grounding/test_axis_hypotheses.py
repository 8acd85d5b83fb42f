"""A body of revolution's goal axis is searched over every direction, not only the sweep's tilts."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pipeline.grounding.compare import sphere_directions, turns_onto
from pipeline.grounding.hypotheses import AXIS_DIRECTIONS, axis_hypotheses
from pipeline.grounding.prepare import prepare
from pipeline.grounding.seen_symmetry import off_support, shape_symmetry
from pipeline.grounding.types import GroundingConfig, GroundingInput, SeenSymmetry

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # bench/ is not an installed package

from bench.pairgen.generate import make_pair


def test_the_directions_cover_the_sphere_and_each_is_reached_by_a_least_rotation():
    """Every axis direction lies within 7 deg of one tried (ICP turns up to 15), and the rotation tried takes the
    capture's axis there."""
    directions = sphere_directions(AXIS_DIRECTIONS)
    anywhere = np.random.default_rng(0).normal(size=(5000, 3))
    anywhere /= np.linalg.norm(anywhere, axis=1, keepdims=True)
    assert np.degrees(np.arccos(np.clip((anywhere @ directions.T).max(axis=1), -1, 1))).max() < 7.0
    a = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    targets = np.vstack([directions, a, -a])  # the same direction and the opposite one too
    R = turns_onto(a, targets)
    assert np.allclose(R @ a, targets, atol=1e-9)
    assert np.allclose(R @ R.transpose(0, 2, 1), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("seed, index", [(2000, 9), (2000, 17)])
def test_a_cylinder_turned_between_the_sweeps_tilts_gets_its_axis(seed, index):
    """Raycast cylinders (bench.pairgen) whose goal axis lies 20-30 deg from every rotation the sweep tries (its tilts
    are 30 deg apart): one of the axis hypotheses puts the axis within 12 deg of the truth, where ICP can take it."""
    p = make_pair(seed, index)
    assert p.object_kind == "cylinder"
    inp = GroundingInput(p.rgb0, p.depth0, p.mask0, p.rgb1, p.depth1, p.depth1_kind, p.mask1, p.intrinsics)
    prepared = prepare(inp, GroundingConfig(), p.T_base_camera)
    up = p.T_base_camera[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    seen0 = off_support(prepared.view0.cloud, prepared.view0.normals, prepared.points0, inp.mask0, up)
    shape = shape_symmetry(*seen0, up)
    assert shape.axis is not None
    found = axis_hypotheses(prepared.view0, prepared.view1, p.intrinsics, shape, prepared.size)
    axis_true = p.T_motion_camera[:3, :3] @ shape.axis
    off = [np.degrees(np.arccos(min(1.0, abs((h.R @ shape.axis) @ axis_true)))) for h in found]
    assert min(off) < 12.0


def test_no_axis_no_hypotheses():
    """A shape with no axis (a box, a handled body) gets none: its turn is the sweep's and the faces' to find."""
    p = make_pair(2000, 0)
    inp = GroundingInput(p.rgb0, p.depth0, p.mask0, p.rgb1, p.depth1, p.depth1_kind, p.mask1, p.intrinsics)
    prepared = prepare(inp, GroundingConfig(), p.T_base_camera)
    shape = SeenSymmetry("none", np.zeros(3))
    assert axis_hypotheses(prepared.view0, prepared.view1, p.intrinsics, shape, prepared.size) == []
