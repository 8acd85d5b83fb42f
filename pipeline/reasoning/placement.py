"""Where a moved object may go on the table: a free, supported spot inside the arm's reach and in the camera's
sight, found from the depth frame alone.

The offline editor asks for a spot in a relation to a reference ("behind the bowl"): candidates fan out from the
ideal one (straight behind, just clear of the reference) to nearby directions and a little farther, then to the
edges of the relation's quadrant (45 deg off), and the first that passes every check is taken; when none does,
the refusal says what stood in the way of each. A spot is
  free       no other object's points (seen above the table) within the object's footprint plus a gap (a place:
             the disc of its radius, where the fingers open; a push's end: its own outline, and nothing on its way),
  supported  the table is under it (the depth there is the table's, not the floor's beyond its edge),
  in reach   its centre within the reach band around the robot base's vertical axis (needs T_base_camera),
  in view    most of the moved object in the image and not hidden behind a nearer object.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from drivers.types import CameraIntrinsics
from pipeline.reasoning.tabletop import Footprint, Plane, axis_rotation

OBSTACLE_HEIGHT_M = (0.008, 0.2)  # points this high are objects (the arm at home hangs its fingertips 0.23 m up)
OFF_TABLE_M = 0.02  # measured depth this far beyond the table plane: no table there
HIDDEN_M = 0.01  # the scene this much nearer than the moved object hides it
MAX_OFF_TABLE = 0.05  # fractions of the footprint / the object allowed off the table / hidden / out of the image
MAX_HIDDEN = 0.5
MAX_OUT_OF_VIEW = 0.3
PATH_STEP_M = 0.01  # a push's path checked this often
PATH_CLEAR_M = 0.005  # how near the pushed object may pass another


@dataclass(frozen=True)
class PlacementConfig:
    # centre's distance from the base's vertical axis [m]: nearer, the arm folds onto itself reaching down there
    reach_m: tuple[float, float] = (0.28, 0.68)
    gap_m: float = 0.02  # free table between the placed object and any other [m]
    pushed_gap_m: float = 0.01  # between a pushed object's outline and any other where it ends (no fingers beside)
    beside_gap_m: float = 0.04  # footprint to footprint when placed beside a reference, at first [m]
    farther_m: tuple[float, ...] = (0.0, 0.02, 0.04, 0.06)  # tried beyond that
    turns_deg: tuple[float, ...] = (0.0, 15.0, -15.0, 30.0, -30.0)  # away from the relation's direction ...
    # ... and, where none of those is free, the edges of the quadrant a person still calls "in front of" (clutter)
    wide_turns_deg: tuple[float, ...] = (45.0, -45.0)


class Table:
    """The table top seen in one depth frame: other objects' points in plane coordinates, and the checks."""

    def __init__(
        self,
        depth_m: np.ndarray,
        K: CameraIntrinsics,
        plane: Plane,
        exclude: np.ndarray,
        T_base_camera: np.ndarray | None,
        config: PlacementConfig,
    ) -> None:
        self.depth, self.K, self.plane, self.T_base_camera, self.config = depth_m, K, plane, T_base_camera, config
        self.e1 = plane.in_plane(np.array([1.0, 0.0, 0.0]))
        self.e2 = np.cross(plane.n, self.e1)
        self.origin = -plane.d * plane.n
        pts = K.unproject_depth_image(depth_m)[::2, ::2]
        keep = ~exclude[::2, ::2] & np.all(np.isfinite(pts), axis=2)
        pts = pts[keep]
        h = plane.height(pts)
        objects = pts[(h > OBSTACLE_HEIGHT_M[0]) & (h < OBSTACLE_HEIGHT_M[1])]
        self.obstacles = cKDTree(self.to_2d(objects)) if len(objects) else None

    def to_2d(self, p: np.ndarray) -> np.ndarray:
        q = np.atleast_2d(p) - self.origin
        return np.stack([q @ self.e1, q @ self.e2], axis=1)

    def problem(
        self, target: Footprint, shift: np.ndarray, hidden_ok: bool = False, pushed: bool = False
    ) -> str | None:
        """Why the target moved by `shift` (camera frame) would not stand there, or None. `hidden_ok`: in a
        container, whose walls may hide it. The gap is kept around the disc of the object's radius where a hand sets
        it down (the fingers open about it there); `pushed`: around its own outline, seen from above (the hand stays
        behind it; see also in_the_way)."""
        centre = target.centre + shift
        crowded = self._near_outline(target, shift) if pushed else self._near_disc(target, centre)
        if crowded is not None:
            return crowded
        ring = _disc(target, centre, self.plane)
        uv, inside = self._pixels(ring)
        if inside.mean() < 1.0 - MAX_OUT_OF_VIEW:
            return "outside the camera's view"
        measured = self.depth[uv[inside, 1], uv[inside, 0]]  # NaN (an edge's flying pixels): not known
        beyond = np.isfinite(measured) & (measured > ring[inside, 2] + OFF_TABLE_M)
        if beyond.sum() > MAX_OFF_TABLE * max(np.isfinite(measured).sum(), 1) or not np.isfinite(measured).any():
            return "off the table"
        reach = self._reach(centre)
        if reach is not None:
            return reach
        moved = target.points + shift
        uv, inside = self._pixels(moved)
        if inside.mean() < 1.0 - MAX_OUT_OF_VIEW:
            return "outside the camera's view"
        seen = self.depth[uv[inside, 1], uv[inside, 0]]
        hidden = np.isfinite(seen) & (seen < moved[inside, 2] - HIDDEN_M)
        if hidden.mean() > MAX_HIDDEN and not hidden_ok:
            return "hidden from the camera behind another object"
        return None

    def _near_disc(self, target: Footprint, centre: np.ndarray) -> str | None:
        if self.obstacles is None:
            return None
        if self.obstacles.query(self.to_2d(centre)[0])[0] < target.radius_m + self.config.gap_m:
            return "too close to another object"
        return None

    def _near_outline(self, target: Footprint, shift: np.ndarray) -> str | None:
        if self.obstacles is None:
            return None
        if self.obstacles.query(self.to_2d(target.points + shift))[0].min() < self.config.pushed_gap_m:
            return "too close to another object"
        return None

    def in_the_way(self, target: Footprint, shift: np.ndarray) -> str | None:
        """Why the target pushed by `shift` (camera frame) would push another object along, or None: one nearer than
        PATH_CLEAR_M to its outline on the way (one it already touches at the start does not count: it stays
        behind or beside)."""
        if self.obstacles is None:
            return None
        outline = self.to_2d(target.points)
        step = (self.to_2d(target.centre + shift) - self.to_2d(target.centre))[0]
        middle = outline.mean(axis=0) + 0.5 * step
        sweep = float(np.max(np.linalg.norm(outline - outline.mean(axis=0), axis=1)) + 0.5 * np.linalg.norm(step))
        near = self.obstacles.data[self.obstacles.query_ball_point(middle, sweep + PATH_CLEAR_M)]
        if not len(near):
            return None
        path = cKDTree(outline)
        near = near[path.query(near)[0] >= PATH_CLEAR_M]  # not already touching
        n = max(2, int(np.ceil(np.linalg.norm(step) / PATH_STEP_M)) + 1)
        for f in np.linspace(0.0, 1.0, n)[1:]:
            if len(near) and path.query(near - f * step)[0].min() < PATH_CLEAR_M:
                return f"another object stands in its way, {f * np.linalg.norm(step) * 100:.0f} cm along"
        return None

    def _pixels(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        front = points[:, 2] > 1e-3
        uv = np.full((len(points), 2), -1, int)
        uv[front] = np.round(self.K.project(points[front])).astype(int)
        h, w = self.depth.shape
        inside = front & (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        return uv, inside

    def _reach(self, centre: np.ndarray) -> str | None:
        if self.T_base_camera is None:
            return None
        p = self.T_base_camera[:3, :3] @ centre + self.T_base_camera[:3, 3]
        r = math.hypot(p[0], p[1])
        lo, hi = self.config.reach_m
        if not lo <= r <= hi:
            return f"out of the arm's reach ({r:.2f} m from the base axis; reach {lo:.2f}-{hi:.2f} m)"
        return None


def _disc(target: Footprint, centre: np.ndarray, plane: Plane, n: int = 24) -> np.ndarray:
    """Points on the table at the target's footprint circle and centre (camera frame)."""
    e1 = plane.in_plane(np.array([1.0, 0.0, 0.0]))
    e2 = np.cross(plane.n, e1)
    a = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    r = target.radius_m
    ring = centre + r * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)
    return plane.project(np.vstack([ring, 0.5 * (ring + centre), centre]))


def spot_beside(
    table: Table, target: Footprint, reference: Footprint, direction: np.ndarray, what: str
) -> tuple[np.ndarray | None, str]:
    """The shift that puts `target` beside `reference` towards `direction` (a unit vector in the plane): the
    first candidate that passes Table.problem, or None and why each failed ("what" names the request)."""
    cfg = table.config
    problems: Counter[str] = Counter()
    tries = [
        (extra, turn) for turns in (cfg.turns_deg, cfg.wide_turns_deg) for extra in cfg.farther_m for turn in turns
    ]
    for extra, turn in tries:
        d = axis_rotation(table.plane.n, math.radians(turn)) @ direction
        base = reach_along(reference, d, table.plane) + reach_along(target, -d, table.plane) + cfg.beside_gap_m
        shift = reference.centre + d * (base + extra) - target.centre
        problem = table.problem(target, shift)
        if problem is None:
            return shift, ""
        problems[_short(problem)] += 1
    tried = sum(problems.values())
    why = ", ".join(f"{n} {p}" for p, n in problems.most_common())
    return None, f"no free spot {what}: {tried} spots tried ({why})"


def reach_along(fp: Footprint, d: np.ndarray, plane: Plane) -> float:
    """How far the object reaches from its centre towards d on the table (a pan's handle that way counts), at
    least its footprint radius (its far side is unseen)."""
    q = plane.project(fp.points) - fp.centre
    return max(fp.radius_m, float(np.percentile(q @ d, 98)))


def _short(problem: str) -> str:
    return problem.split(" (")[0]
