"""The turn of a body of revolution with a handle (a mug, a pan) standing on the table, from where its handle points.

The body shows no turn about the vertical; only the handle does, and it is too thin for a model's bled goal depth to
place it among the points, so the geometric agreement hardly tells a mug's turns apart. Seen from above, though, the
handle is where the outline reaches out beyond the round body (seen_symmetry.handle_azimuth), in both views: the turn
about the vertical that carries the one direction onto the other, about the body's axis, is offered as a
hypothesis (raycast mugs were 50-175 deg off).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from pipeline.grounding.seen_symmetry import handle_azimuth, standing_axis, vertical_axis_centre
from pipeline.grounding.umeyama import Similarity


def handle_hypotheses(
    seen0: tuple[np.ndarray, np.ndarray], seen1: tuple[np.ndarray, np.ndarray], up: np.ndarray
) -> list[Similarity]:
    """The turn about the vertical `up` (camera frame) that brings the handle of the body standing in the capture
    (`seen0`: its points above the support and their normals) to where the goal's points (`seen1`) show it, the
    body's axis onto the goal's; none unless the capture shows a standing body with a handle and the goal a handle."""
    up = up / np.linalg.norm(up)
    standing = standing_axis(*seen0, up)
    c1 = vertical_axis_centre(*seen1, up)  # the goal's normals are too noisy to test, only to place the axis
    if standing is None or c1 is None:
        return []
    c0, a = standing
    h0, h1 = handle_azimuth(seen0[0], c0, a), handle_azimuth(seen1[0], c1, a)
    if h0 is None or h1 is None:
        return []
    R = Rotation.from_rotvec((h1 - h0) * a).as_matrix()
    return [Similarity(1.0, R, c1 - R @ c0)]
