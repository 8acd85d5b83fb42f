"""Collision-free joint-space paths with OMPL, checked against the safety collision world.

A direct straight-line move is tried first. Otherwise an OMPL planner (RRTConnect by default) searches within
the joint limits minus the safety margin, with the collision world's `in_collision` as validity checker. The
search checks motions coarsely (search_resolution_rad, halved on each retry); the solution is then shortcut
greedily with this module's own dense check (resolution_rad, coarse-to-fine order), so every segment of the
returned path has passed the dense check and a simplified path that clips an obstacle is never returned.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from motion.limits import MotionLimits
from safety.collision import CollisionWorld

PlannerName = Literal["RRTConnect", "RRT", "RRTstar", "InformedRRTstar", "BITstar", "PRM", "KPIECE1", "BKPIECE1"]
ou.setLogLevel(ou.LOG_WARN)
ou.RNG.setSeed(1)  # OMPL seeds once per process, before its first sampler: runs are reproducible in order


class PlanningError(RuntimeError):
    """No collision-free path was found or the query itself is invalid; the message says which and why."""


@dataclass(frozen=True)
class PlannerConfig:
    planner: PlannerName = "RRTConnect"
    timeout_s: float = 1.0  # search budget per attempt
    attempts: int = 3  # fresh searches before giving up
    range_rad: float | None = 1.0  # longest tree extension (planners with a range); None: OMPL's default
    search_resolution_rad: float = 0.05  # motion-check step during the search (halved on each retry)
    resolution_rad: float = 0.005  # largest joint motion between the final path's collision checks
    cut_clearance_m: float = 0.005  # extra obstacle clearance a corner cut must keep (Planner.smooth)
    window_rad: float = np.pi  # continuous joints are searched within this of the start/goal range


@dataclass(frozen=True)
class JointPath:
    waypoints: np.ndarray  # (M, dof) [rad], first = start, last = goal
    method: str  # "direct" or the planner's name
    planning_time_s: float


class Planner:
    """Plans in one collision world (not thread-safe, like the world: use one planner per thread)."""

    def __init__(self, world: CollisionWorld, limits: MotionLimits, config: PlannerConfig | None = None) -> None:
        self.world, self.limits = world, limits
        self.config = config or PlannerConfig()
        self.dof = limits.dof

    # -- checks ------------------------------------------------------------------------------------------------
    def valid(self, q: np.ndarray) -> bool:
        q = np.asarray(q, dtype=np.float64)
        inside = np.all(q >= self.limits.lower) and np.all(q <= self.limits.upper)
        return bool(inside) and not self.world.in_collision(q)

    def segment_free(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        """Every configuration on the straight line qa-qb, checked every resolution_rad of joint motion (coarse
        to fine, so a blocked line is usually rejected after a few checks)."""
        n = max(1, int(np.ceil(np.max(np.abs(qb - qa)) / self.config.resolution_rad)))
        return all(self.valid(qa + (qb - qa) * (k / n)) for k in coarse_to_fine(n))

    def why_invalid(self, q: np.ndarray, what: str) -> str:
        low, high = q < self.limits.lower, q > self.limits.upper
        if np.any(low | high):
            j = int(np.flatnonzero(low | high)[0])
            return (
                f"{what} joint {j + 1} = {q[j]:.4f} rad is outside "
                f"[{self.limits.lower[j]:.4f}, {self.limits.upper[j]:.4f}] (limits minus margin)"
            )
        contacts = ", ".join(f"{c.first} / {c.second} ({c.kind})" for c in self.world.check(q)[:3])
        return f"{what} configuration is in collision: {contacts}"

    # -- planning ----------------------------------------------------------------------------------------------
    def plan(self, q_start: np.ndarray, q_goal: np.ndarray) -> JointPath:
        t0 = time.perf_counter()
        q_start, q_goal = (np.asarray(q, dtype=np.float64).reshape(self.dof) for q in (q_start, q_goal))
        for q, what in ((q_start, "start"), (q_goal, "goal")):
            if not self.valid(q):
                raise PlanningError(self.why_invalid(q, what))
        if self.segment_free(q_start, q_goal):
            return JointPath(np.array([q_start, q_goal]), "direct", time.perf_counter() - t0)
        for attempt in range(self.config.attempts):
            step = max(self.config.search_resolution_rad / 2**attempt, self.config.resolution_rad)
            waypoints = self._search(q_start, q_goal, step)
            if waypoints is not None:
                return JointPath(waypoints, self.config.planner, time.perf_counter() - t0)
        raise PlanningError(
            f"{self.config.planner} found no collision-free path in {self.config.attempts} x "
            f"{self.config.timeout_s} s from {np.round(q_start, 3)} to {np.round(q_goal, 3)}"
        )

    def smooth(self, waypoints: np.ndarray, fraction: float = 0.25) -> np.ndarray:
        """Cut the corners of a path for blended execution: interior waypoint i becomes the two points `fraction`
        of the way towards its neighbours, where the straight cut between them is free with every obstacle grown
        by `cut_clearance_m` (else half the fraction, else the corner stays). A cut is optional, so it is held to
        the stricter test: the extra clearance covers what could hide between two checks, so the gate's own
        checks at other configurations find no contact. The rest of the path stays on the checked segments."""
        if not 0 < fraction <= 0.5:
            raise ValueError(f"fraction must be in (0, 0.5] so neighbouring cuts do not cross, got {fraction}")
        strict = Planner(self._inflated_world(), self.limits, self.config)
        out = [waypoints[0]]
        for prev, corner, nxt in zip(waypoints[:-2], waypoints[1:-1], waypoints[2:], strict=True):
            for f in (fraction, fraction / 2):
                a, b = corner + f * (prev - corner), corner + f * (nxt - corner)
                if strict.segment_free(a, b):
                    out += [a, b]
                    break
            else:
                out.append(corner)
        out.append(waypoints[-1])
        return np.array(out)

    def _inflated_world(self) -> CollisionWorld:
        """The world with every obstacle grown by cut_clearance_m (self-collision, table and point cloud as is)."""
        w = self.world
        return CollisionWorld(
            w.robot.copy(),
            w.config,
            obstacles=[o.padded(self.config.cut_clearance_m) for o in w.obstacles],
            points=w.points,
            held=w.held_object,
            gripper_width_m=w.gripper_width_m,
        )

    def _bounds(self, q_start: np.ndarray, q_goal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint limits, narrowed for wide joints to a window around start and goal (a 4 pi range mostly
        offers detours; narrowing speeds up the search and shortens paths)."""
        lo = np.maximum(self.limits.lower, np.minimum(q_start, q_goal) - self.config.window_rad)
        hi = np.minimum(self.limits.upper, np.maximum(q_start, q_goal) + self.config.window_rad)
        return lo, hi

    def _search(self, q_start: np.ndarray, q_goal: np.ndarray, step_rad: float) -> np.ndarray | None:
        space = ob.RealVectorStateSpace(self.dof)
        lo, hi = self._bounds(q_start, q_goal)
        bounds = ob.RealVectorBounds(self.dof)
        for j in range(self.dof):
            bounds.setLow(j, float(lo[j]))
            bounds.setHigh(j, float(hi[j]))
        space.setBounds(bounds)
        space.setLongestValidSegmentFraction(step_rad / space.getMaximumExtent())
        setup = og.SimpleSetup(space)
        dof, in_collision = self.dof, self.world.in_collision
        setup.setStateValidityChecker(lambda s: not in_collision(np.fromiter((s[i] for i in range(dof)), float, dof)))
        start, goal = space.allocState(), space.allocState()
        for j in range(self.dof):
            start[j], goal[j] = float(q_start[j]), float(q_goal[j])
        setup.setStartAndGoalStates(start, goal)
        planner = getattr(og, self.config.planner)(setup.getSpaceInformation())
        if self.config.range_rad and hasattr(planner, "setRange"):
            planner.setRange(self.config.range_rad)
        setup.setPlanner(planner)
        if not setup.solve(self.config.timeout_s) or not setup.haveExactSolutionPath():
            return None
        raw = _waypoints(setup.getSolutionPath(), self.dof)
        raw[0], raw[-1] = q_start, q_goal
        return self._shortcut(raw)

    def _shortcut(self, raw: np.ndarray) -> np.ndarray | None:
        """From each kept vertex jump to the farthest later vertex joined by a densely checked free line: fewer
        waypoints, and every returned segment already passed the dense check. None when a raw edge itself fails
        it (the coarse search step let it clip an obstacle)."""
        keep, i = [0], 0
        while i < len(raw) - 1:
            j = next((j for j in range(len(raw) - 1, i, -1) if self.segment_free(raw[i], raw[j])), None)
            if j is None:
                return None
            keep.append(j)
            i = j
        return raw[keep]


def _waypoints(path: og.PathGeometric, dof: int) -> np.ndarray:
    return np.array([[path.getState(i)[j] for j in range(dof)] for i in range(path.getStateCount())])


def coarse_to_fine(n: int):
    """0..n, every 2^m-th index first, then the ones in between, halving the stride down to 1."""
    stride = 1 << max(0, n.bit_length() - 1)
    yield from range(0, n + 1, stride)
    while stride > 1:
        yield from range(stride // 2, n + 1, stride)
        stride //= 2
