"""The grasped object as the gate sees it while it rides in the gripper: one box in the TCP frame."""

from __future__ import annotations

import numpy as np

from safety.geometry import Primitive, transform_points

UPRIGHT_COS = 0.9  # a closing axis this close to vertical leaves no upright direction across it


def held_box(points_base: np.ndarray, T_base_tcp: np.ndarray, *, tcp_link: str, name: str) -> Primitive:
    """The grasped object as a box in the TCP frame: the points' extent, mirrored about the TCP across the closing
    axis (y) only. The fingers close on the object's middle along y, whose far side the camera may not see; along
    the pads (x) the seen extent is the object's (its top is seen whole), and mirroring it there would give an
    object grasped off its middle (a long bottle) a phantom end that, once the object is turned, reaches into the
    table or the arm. The box's other axes are the upright across the closing axis and the one square to both: a
    grasp leaning about its closing axis holds a block as it stands, whose box in the leaning TCP axes would be
    a third larger and reach into the table and its neighbours."""
    y = T_base_tcp[:3, 1]
    down = np.array([0.0, 0.0, -1.0])
    R_tcp_box = np.eye(3)
    if abs(y @ down) < UPRIGHT_COS:
        z = down - (down @ y) * y
        z /= np.linalg.norm(z)
        R_tcp_box = T_base_tcp[:3, :3].T @ np.column_stack([np.cross(y, z), y, z])
    local = transform_points(np.linalg.inv(T_base_tcp), points_base) @ R_tcp_box  # box axes, about the TCP
    x0, x1 = float(local[:, 0].min()), float(local[:, 0].max())
    half_y = float(np.max(np.abs(local[:, 1])))
    z0, z1 = float(local[:, 2].min()), float(local[:, 2].max())
    T = np.eye(4)
    T[:3, :3] = R_tcp_box
    T[:3, 3] = R_tcp_box @ np.array([(x0 + x1) / 2, 0.0, (z0 + z1) / 2])
    return Primitive(f"held:{name}", tcp_link, "box", (x1 - x0, 2 * half_y, z1 - z0), T)
