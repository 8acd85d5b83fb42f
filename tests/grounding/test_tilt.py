"""A motion's small tilt of the vertical is taken out unless the views show it."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.compare import rotation_deg
from pipeline.grounding.tilt import TURNED_OVER_MARGIN, kept_level, level_twin, ranks_above
from pipeline.grounding.umeyama import Similarity

UP = np.array([0.0, -0.6, -0.8])
CENTRE = np.array([0.02, 0.05, 0.6])


def _motion(yaw_deg: float, tilt_deg: float) -> Similarity:
    """A yaw about the vertical then a tilt about a horizontal axis, about CENTRE, and a slide."""
    across = np.cross(UP, [1.0, 0.0, 0.0])
    R = (
        Rotation.from_rotvec(np.radians(tilt_deg) * across / np.linalg.norm(across))
        * Rotation.from_rotvec(np.radians(yaw_deg) * UP)
    ).as_matrix()
    return Similarity(1.0, R, CENTRE + np.array([0.1, 0.0, 0.02]) - R @ CENTRE)


def test_the_level_twin_keeps_the_yaw_and_where_the_object_goes():
    motion = _motion(40.0, 20.0)
    level = level_twin(motion, UP, CENTRE)
    np.testing.assert_allclose(level.R @ UP, UP, atol=1e-9)  # no tilt left
    np.testing.assert_allclose(level.apply(CENTRE[None]), motion.apply(CENTRE[None]), atol=1e-9)
    assert abs(rotation_deg(level.R.T @ _motion(40.0, 0.0).R)) < 1e-6  # the yaw kept
    assert level_twin(_motion(40.0, 45.0), UP, CENTRE) is None  # a tip is no small tilt
    assert level_twin(_motion(40.0, 0.0), UP, CENTRE) is None


def test_a_tilt_is_kept_only_where_the_views_show_it():
    motion, level = _motion(40.0, 20.0), _motion(40.0, 0.0)

    def tilt_of(m: Similarity) -> float:
        return np.degrees(np.arccos(np.clip(m.R @ UP @ UP, -1, 1)))

    def views_agree(shown_by: float):  # geometric agreement that falls off with the distance from the true tilt
        return lambda m: 0.8 - shown_by * abs(tilt_of(m) - 20.0) / 20.0

    # a model's warped goal depth favours a false tilt by up to 0.05: the views cannot tell
    assert rotation_deg(kept_level(motion, UP, CENTRE, views_agree(0.05)).R.T @ level.R) < 1e-6
    assert kept_level(motion, UP, CENTRE, views_agree(0.09)) is motion  # they show the tilt


def test_a_motion_turning_the_object_over_must_rank_clearly_above_one_keeping_it_up():
    """Upside down (170 deg) against upright (10 deg): the upright one wins unless the other ranks TURNED_OVER_MARGIN
    above it. Laid on its side either way (80 against 100 deg: which end leads says nothing of up), rank alone decides;
    so it does between two upright motions."""
    over, kept = _motion(0.0, 170.0).R, _motion(30.0, 10.0).R
    assert not ranks_above(0.6 + 0.9 * TURNED_OVER_MARGIN, over, 0.6, kept, UP)
    assert ranks_above(0.6, kept, 0.6 + 0.9 * TURNED_OVER_MARGIN, over, UP)
    assert ranks_above(0.6 + 1.1 * TURNED_OVER_MARGIN, over, 0.6, kept, UP)
    assert ranks_above(0.61, _motion(0.0, 100.0).R, 0.6, _motion(0.0, 80.0).R, UP)
    assert not ranks_above(0.59, _motion(0.0, 100.0).R, 0.6, _motion(0.0, 80.0).R, UP)
    assert ranks_above(0.61, kept, 0.6, _motion(0.0, 0.0).R, UP)
