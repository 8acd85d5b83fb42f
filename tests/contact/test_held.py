"""The grasped object's box in the TCP frame, as the gate checks it during the carry."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.contact.held import held_box


def test_held_box_is_mirrored_across_the_closing_axis_only():
    # the seen top and front of a 0.18 m long, 0.06 m wide bar, grasped from above 0.05 m off its middle
    rng = np.random.default_rng(0)
    points = rng.uniform([-0.09, -0.03, 0.0], [0.09, 0.01, 0.06], (500, 3)) + np.array([0.45, 0.0, 0.0])
    T_base_tcp = np.diag([1.0, -1.0, -1.0, 1.0])  # pointing down, pads along base x, closing along base y
    T_base_tcp[:3, 3] = (0.50, -0.01, 0.03)
    box = held_box(points, T_base_tcp, tcp_link="link_tcp", name="bar")
    size, centre = np.asarray(box.size), box.T_link_geom[:3, 3]
    assert size[0] == pytest.approx(0.18, abs=0.002)  # along the pads: the seen length, no phantom end
    assert centre[0] == pytest.approx(-0.05, abs=0.002)
    assert size[1] == pytest.approx(0.04, abs=0.002)  # across: the farther seen side mirrored about the TCP
    assert centre[1] == 0.0
    assert size[2] == pytest.approx(0.06, abs=0.002)
