"""The grasped object as the gate sees it while it rides in the gripper: one box in the TCP frame."""

from __future__ import annotations

import numpy as np

from safety.geometry import Primitive, transform_points


def held_box(points_base: np.ndarray, T_base_tcp: np.ndarray, *, tcp_link: str, name: str) -> Primitive:
    """The grasped object as a box in the TCP frame: the points' extent, mirrored about the TCP across the closing
    axis (y) only. The fingers close on the object's middle along y, whose far side the camera may not see; along
    the pads (x) the seen extent is the object's (its top is seen whole), and mirroring it there would give an
    object grasped off its middle (a long bottle) a phantom end that, once the object is turned, reaches into the
    table or the arm."""
    local = transform_points(np.linalg.inv(T_base_tcp), points_base)
    x0, x1 = float(local[:, 0].min()), float(local[:, 0].max())
    half_y = float(np.max(np.abs(local[:, 1])))
    z0, z1 = float(local[:, 2].min()), float(local[:, 2].max())
    T = np.eye(4)
    T[0, 3], T[2, 3] = (x0 + x1) / 2, (z0 + z1) / 2
    return Primitive(f"held:{name}", tcp_link, "box", (x1 - x0, 2 * half_y, z1 - z0), T)
