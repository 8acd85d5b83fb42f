"""The collision world: the robot at a configuration against itself, the table, the workspace walls, keep-out
boxes, obstacles, a point cloud and the object in its hand.

    world = CollisionWorld(RobotModel(), SafetyConfig(), obstacles=desc.obstacles(), points=cloud)
    world.in_collision(q)      # fast path (~15-20 us), e.g. the OMPL validity checker
    world.check(q)             # every contact, with kind and names, for reports

Every robot primitive is grown by config.padding_m. Changing obstacles, points or the held object rebuilds the
backend (milliseconds); changing the gripper width does not. Not thread-safe: use copy() per thread.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from safety.config import SafetyConfig
from safety.geometry import Primitive
from safety.robot_model import RobotModel
from safety.scene import CollisionKind, Scene, build_scene
from safety.world import WorldDescription

BackendName = Literal["coal", "fcl"]


@dataclass(frozen=True)
class Contact:
    """One colliding pair: `first` is a robot primitive (e.g. "link3/0", "left_finger/pad") or the held object
    ("held:<name>"), `second` the other object (a robot primitive, "table", "workspace:+x", "keep_out:<name>",
    an obstacle name, or "point_cloud")."""

    kind: CollisionKind
    first: str
    second: str


class CollisionWorld:
    def __init__(
        self,
        robot: RobotModel | None = None,
        config: SafetyConfig | None = None,
        *,
        obstacles: list[Primitive] = (),
        points: np.ndarray | None = None,
        held: Primitive | None = None,
        gripper_width_m: float | None = None,
        table: bool = True,
        backend: BackendName = "coal",
        held_padding_m: float | None = None,
    ) -> None:
        """held_padding_m: how much the held object is grown (default the robot's padding_m). A tool meant to
        touch the table or to skim past objects (a brush's bristles) is checked with its own, smaller margin;
        every robot shape keeps padding_m."""
        self.robot = robot or RobotModel()
        self.config = config or SafetyConfig()
        self.backend_name: BackendName = backend
        self._obstacles = list(obstacles)
        self._points = None if points is None else np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self._held = held
        self._table = table
        if held_padding_m is not None and not 0.0 <= held_padding_m <= self.config.padding_m:
            raise ValueError(f"held_padding_m {held_padding_m} outside [0, padding_m = {self.config.padding_m}]")
        self._held_padding = held_padding_m
        self._qf = self.robot.full_q(self.robot.home_q)
        self._finger_idx = self.robot.finger_q_indices
        self._half_gap = 0.0
        self.set_gripper_width(self.robot.spec.gripper.max_width_m if gripper_width_m is None else gripper_width_m)
        self._rebuild()

    @classmethod
    def from_description(
        cls,
        robot: RobotModel | None,
        config: SafetyConfig | None,
        description: WorldDescription,
        points: np.ndarray | None = None,
        backend: BackendName = "coal",
    ) -> CollisionWorld:
        """World from a validated WORLD.json (see safety.world.load_world_file for the points)."""
        robot = robot or RobotModel()
        held = description.held_object.primitive(robot.tcp_frame) if description.held_object else None
        return cls(
            robot,
            config,
            obstacles=description.obstacles(),
            points=points,
            held=held,
            gripper_width_m=description.gripper_width_m,
            backend=backend,
        )

    def copy(self, backend: BackendName | None = None) -> CollisionWorld:
        """An independent world with the same contents (own robot model), e.g. for another thread."""
        return CollisionWorld(
            self.robot.copy(),
            self.config,
            obstacles=self._obstacles,
            points=self._points,
            held=self._held,
            gripper_width_m=self.gripper_width_m,
            table=self._table,
            backend=backend or self.backend_name,
            held_padding_m=self._held_padding,
        )

    def holding(self, held: Primitive) -> CollisionWorld:
        """The same world (scene, table, held margin) with `held` in the hand."""
        return CollisionWorld(
            self.robot,
            self.config,
            obstacles=self._obstacles,
            points=self._points,
            held=held,
            gripper_width_m=self.gripper_width_m,
            table=self._table,
            backend=self.backend_name,
            held_padding_m=self._held_padding,
        )

    # ---- contents ----------------------------------------------------------------------------------------------
    @property
    def obstacles(self) -> tuple[Primitive, ...]:
        return tuple(self._obstacles)

    @property
    def points(self) -> np.ndarray | None:
        return self._points

    @property
    def held_object(self) -> Primitive | None:
        return self._held

    @property
    def gripper_width_m(self) -> float:
        """The current finger gap [m], used by queries that give none."""
        return 2 * self._half_gap

    def set_gripper_width(self, width_m: float) -> None:
        """Record the gripper's present opening (from its state); clamped to the stroke."""
        self._half_gap = self._half(width_m)

    def _half(self, width_m: float) -> float:
        g = self.robot.spec.gripper
        return float(np.clip(width_m, g.min_width_m, g.max_width_m)) / 2

    def set_obstacles(self, obstacles: list[Primitive]) -> None:
        self._obstacles = list(obstacles)
        self._rebuild()

    def set_points(self, points: np.ndarray | None) -> None:
        """Point-cloud obstacle (N, 3) in the base frame; see safety.pointcloud for filtering a camera frame."""
        self._points = None if points is None else np.asarray(points, dtype=np.float64).reshape(-1, 3)
        self._rebuild()

    def set_held_object(self, held: Primitive | None) -> None:
        """Object in the gripper, attached to the TCP frame (Primitive.link = robot.tcp_frame); None to release."""
        if held is not None and held.link != self.robot.tcp_frame:
            raise ValueError(f"held object must be attached to {self.robot.tcp_frame!r}, got {held.link!r}")
        self._held = held
        self._rebuild()

    def _rebuild(self) -> None:
        self.scene: Scene = build_scene(
            self.robot, self.config, self._obstacles, self._points, self._held, self._table, self._held_padding
        )
        if self.backend_name == "coal":
            from safety.backend_coal import CoalBackend

            self._backend = CoalBackend(self.robot, self.scene)
        elif self.backend_name == "fcl":
            from safety.backend_fcl import FclBackend

            self._backend = FclBackend(self.robot, self.scene)
        else:
            raise ValueError(f"unknown collision backend {self.backend_name!r} (coal or fcl)")

    # ---- queries -----------------------------------------------------------------------------------------------
    def _full(self, q: np.ndarray, gripper_width_m: float | None) -> np.ndarray:
        self._qf[: self.robot.dof] = q
        self._qf[self._finger_idx] = self._half_gap if gripper_width_m is None else self._half(gripper_width_m)
        return self._qf

    def in_collision(self, q: np.ndarray, gripper_width_m: float | None = None) -> bool:
        """True when any checked pair touches (padded). Covers self, table, workspace, keep-out, obstacles, cloud
        and held object; joint limits are NOT part of this (see safety.limits). gripper_width_m applies to this
        call only (default: gripper_width_m property)."""
        return self._backend.in_collision(self._full(q, gripper_width_m))

    def check(self, q: np.ndarray, gripper_width_m: float | None = None) -> list[Contact]:
        """Every touching pair at q, with the violation kind."""
        objs, pairs = self.scene.objects, self.scene.pairs
        contacts = [
            Contact(pairs[k][2], objs[pairs[k][0]].name, objs[pairs[k][1]].name)
            for k in self._backend.colliding_pairs(self._full(q, gripper_width_m))
        ]
        return list(dict.fromkeys(contacts))  # one entry per link even when several cloud chunks touch it
