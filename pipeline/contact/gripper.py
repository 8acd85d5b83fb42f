"""The gripper's collision boxes in the TCP frame, from the safety robot model, for fast candidate checks."""

from __future__ import annotations

import numpy as np

from safety.geometry import Primitive, robot_primitives, transform_points
from safety.robot_model import RobotModel

UNIT_CORNERS = np.array([[sx, sy, sz] for sx in (-0.5, 0.5) for sy in (-0.5, 0.5) for sz in (-0.5, 0.5)])


class GripperBoxes:
    """Gripper body and finger boxes at a given opening, posed by T_base_tcp; checks against points and table."""

    def __init__(self, robot: RobotModel, padding_m: float) -> None:
        self.robot = robot
        g = robot.spec.gripper
        self.links = (g.parent, *g.finger_links)
        self.prims = [p.padded(padding_m) for p in robot_primitives(robot.spec) if p.link in self.links]
        self._cache: dict[float, list[tuple[Primitive, np.ndarray]]] = {}

    def boxes_tcp(self, width_m: float) -> list[tuple[Primitive, np.ndarray]]:
        """(primitive, T_tcp_geom) for every gripper shape with the fingers at width_m."""
        key = round(width_m, 4)
        if key not in self._cache:
            q = self.robot.home_q
            T_tcp_base = np.linalg.inv(self.robot.tcp_pose(q))
            poses = {link: T_tcp_base @ self.robot.frame_pose(q, link, width_m) for link in self.links}
            self._cache[key] = [(p, poses[p.link] @ p.T_link_geom) for p in self.prims]
        return self._cache[key]

    def corners_tcp(self, width_m: float, links: tuple[str, ...] | None = None) -> np.ndarray:
        """Corners (K, 3), TCP frame, of the gripper boxes (of `links` only, when given)."""
        return np.vstack(
            [
                transform_points(T_tcp_geom, UNIT_CORNERS * np.asarray(prim.size))
                for prim, T_tcp_geom in self.boxes_tcp(width_m)
                if prim.kind == "box" and (links is None or prim.link in links)
            ]
        )

    def hits_points(self, T_base_tcp: np.ndarray, width_m: float, points_base: np.ndarray) -> bool:
        if len(points_base) == 0:
            return False
        near = np.linalg.norm(points_base - T_base_tcp[:3, 3], axis=1) < 0.3
        pts = points_base[near]
        for prim, T_tcp_geom in self.boxes_tcp(width_m):
            T_geom_base = np.linalg.inv(T_base_tcp @ T_tcp_geom)
            if prim.contains(transform_points(T_geom_base, pts)).any():
                return True
        return False

    def lowest_z(self, T_base_tcp: np.ndarray, width_m: float) -> float:
        """Lowest point of the gripper boxes in the base frame (the table top is z = 0)."""
        return float(transform_points(T_base_tcp, self.corners_tcp(width_m))[:, 2].min())
