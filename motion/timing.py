"""Jerk-limited time-parameterisation of joint-space paths with Ruckig, sampled at the control period.

Community Ruckig cannot pass intermediate waypoints offline, so a path is timed as a chain of state-to-state
segments. Baseline: the arm rests at every waypoint and each segment is phase-synchronised, so every joint moves
on the straight joint-space line the planner validated. Blended: interior waypoints are crossed at a chosen
velocity (no stop); a blended segment bends away from the straight line, so it is kept only where the caller's
check (the safety gate) accepts the sampled result, and rejected segments fall back to rest-to-rest one by one.
A segment whose TCP would move faster than the Cartesian limit is re-timed with uniformly scaled limits.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Literal

import numpy as np
from ruckig import RuckigError, Trajectory

from motion.blending import crossing_velocities, drop_blends_at
from motion.limits import MotionLimits
from motion.segments import TimingError, ruckig_segment, scaled_limits
from safety.trajectory import GripperEvent, JointTrajectory

# A blended segment too fast for the TCP cap is slowed (with its crossings) unless that takes a factor below this.
MIN_BLEND_SLOWDOWN = 0.5
# Re-timing rounds per waypoint before blending gives up on a path (each round slows or drops a blend).
MAX_BLEND_ROUNDS = 8
# A segment whose sampled TCP speed exceeds TCP_SPEED_ACCEPT of the limit is re-timed to reach TCP_SPEED_TARGET.
TCP_SPEED_ACCEPT, TCP_SPEED_TARGET = 0.99, 0.97
# A check returns the times [s] of the samples it rejects (empty: accepted).
Check = Callable[[JointTrajectory], Sequence[float]]
TcpPositions = Callable[[np.ndarray], np.ndarray]  # (N, dof) -> (N, 3), e.g. RobotModel.tcp_positions


class _TooFast(TimingError):
    def __init__(self, peak: float, limit: float) -> None:
        super().__init__(f"TCP speed {peak:.3f} m/s above {limit} m/s in a blended segment")
        self.factor = limit * TCP_SPEED_TARGET / peak  # uniform slow-down that would bring it under


class _Unblendable(Exception):
    """Segment `segment` of path `path` failed with its crossing velocities; factor > 0: slowing it (limits and
    both crossings) by this factor may fix it, 0: it must stop at its ends."""

    def __init__(self, path: int, segment: int, factor: float) -> None:
        super().__init__(f"path {path} segment {segment}")
        self.path, self.segment, self.factor = path, segment, factor


@dataclass(frozen=True)
class GripperAction:
    """Gripper step between path pieces; the arm holds still for duration_s [s] while it runs."""

    kind: Literal["open", "close", "wait"]
    duration_s: float
    width_m: float = 0.0


@dataclass(frozen=True)
class _Hold:
    q: np.ndarray
    duration: float
    event: GripperAction


Piece = Trajectory | _Hold
Step = np.ndarray | GripperAction


class TrajectoryTimer:
    """Times joint paths and gripper actions for one arm at one control period dt [s]."""

    def __init__(
        self,
        limits: MotionLimits,
        dt: float,
        joint_names: tuple[str, ...],
        tcp_positions: TcpPositions | None = None,
        max_tcp_speed_m_s: float = np.inf,
    ) -> None:
        self.limits, self.dt, self.joint_names = limits, dt, tuple(joint_names)
        self.tcp_positions, self.max_tcp_speed = tcp_positions, max_tcp_speed_m_s

    # -- segments ----------------------------------------------------------------------------------------------
    def rest_segment(self, q0: np.ndarray, q1: np.ndarray) -> tuple[Trajectory, float]:
        """Rest-to-rest straight-line segment, and the uniform limit scale (<= 1) that kept its sampled TCP speed
        under the Cartesian limit."""
        zero, scale = np.zeros(self.limits.dof), 1.0
        traj = ruckig_segment(q0, zero, q1, zero, self.limits)
        for _ in range(4):
            peak = self._tcp_peak(traj)
            if peak <= self.max_tcp_speed * TCP_SPEED_ACCEPT:
                break
            scale *= self.max_tcp_speed * TCP_SPEED_TARGET / peak
            traj = ruckig_segment(q0, zero, q1, zero, scaled_limits(self.limits, scale))
        return traj, scale

    def blended_segment(self, q0, v0, q1, v1, scale: float) -> Trajectory:
        """State-to-state segment at the limits scaled like its rest-to-rest version; TimingError when its TCP
        would still be too fast (it cannot slow down further and still meet its crossing velocities)."""
        traj = ruckig_segment(q0, v0, q1, v1, scaled_limits(self.limits, scale))
        peak = self._tcp_peak(traj)
        if peak > self.max_tcp_speed * TCP_SPEED_ACCEPT:
            raise _TooFast(peak, self.max_tcp_speed)
        return traj

    def _tcp_peak(self, traj: Trajectory) -> float:
        if self.tcp_positions is None or not np.isfinite(self.max_tcp_speed) or traj.duration <= 0:
            return 0.0
        t = np.append(np.arange(0.0, traj.duration, self.dt), traj.duration)
        p = self.tcp_positions(np.array([traj.at_time(x)[0] for x in t]))
        return float(np.max(np.linalg.norm(np.diff(p, axis=0), axis=1) / np.maximum(np.diff(t), 1e-12)))

    # -- whole sequences ---------------------------------------------------------------------------------------
    def time(self, steps: Sequence[Step], blend: bool = False, check: Check | None = None) -> JointTrajectory:
        """Time joint paths (M, dof) and gripper actions into one trajectory sampled every dt.

        blend=False: rest at every waypoint (the straight lines the planner validated). blend=True: cross interior
        waypoints without stopping where `check` (required) accepts the result; a segment holding a rejected
        sample, or leaving the joint limits, loses its crossing velocities and the chain is re-timed, until the
        check passes. The rest-to-rest trajectory is returned instead whenever blending would not be faster or
        nothing is left to blend (the caller's gate then judges it like an unblended one).
        """
        steps = self._checked(steps)
        if blend and check is None:
            raise TimingError("blended timing needs a check (the safety gate) to accept the bent segments")
        paths = [s for s in steps if not isinstance(s, GripperAction)]
        rest = [[self.rest_segment(a, b) for a, b in pairwise(p)] for p in paths]
        stop = self._sample(self._pieces(steps, [np.zeros_like(p) for p in paths], rest, []))[0]
        if not blend:
            return stop
        velocities = [crossing_velocities(p, r, self.limits) for p, r in zip(paths, rest, strict=True)]
        slow = [np.ones(len(p) - 1) for p in paths]  # extra slow-down of blended segments for the TCP cap
        for _ in range(MAX_BLEND_ROUNDS * sum(len(p) for p in paths)):
            try:
                pieces = self._pieces(steps, velocities, rest, slow)
            except _Unblendable as e:  # slow this segment and its crossings down, or make it stop at its ends
                k, crossing = e.segment, velocities[e.path][e.segment : e.segment + 2]
                if e.factor > MIN_BLEND_SLOWDOWN:
                    crossing *= e.factor
                    slow[e.path][k] *= e.factor
                else:
                    crossing[:] = 0.0
                continue
            traj, starts = self._sample(pieces)
            if traj.duration_s >= stop.duration_s:  # slowed so much that stopping is as fast: take the straight lines
                return stop
            bad_times = list(check(traj)) + self._outside_limits(traj)
            if not bad_times:
                return traj
            if not any(np.any(v) for v in velocities):
                return stop
            drop_blends_at(bad_times, starts, _owners(steps), velocities, self.dt)
        return stop  # no accepted blend within the round budget

    def _checked(self, steps: Sequence[Step]) -> list[Step]:
        out: list[Step] = []
        for i, s in enumerate(steps):
            if isinstance(s, GripperAction):
                if s.duration_s < 0:
                    raise TimingError(f"step {i}: gripper {s.kind} needs a duration >= 0, got {s.duration_s}")
                out.append(s)
                continue
            p = np.asarray(s, dtype=np.float64)
            if p.ndim != 2 or p.shape[1] != self.limits.dof or len(p) < 1 or not np.all(np.isfinite(p)):
                raise TimingError(f"step {i}: need finite waypoints of shape (M, {self.limits.dof}), got {p.shape}")
            try:
                self.limits.check_positions(p, f"step {i} waypoint")
            except ValueError as e:
                raise TimingError(str(e)) from None
            out.append(p)
        paths = [s for s in out if not isinstance(s, GripperAction)]
        if not paths:
            raise TimingError("nothing to time: no joint path among the steps")
        if isinstance(out[0], GripperAction):
            raise TimingError("the first step must be a joint path (a gripper action holds the arm where it is)")
        for i, (a, b) in enumerate(pairwise(paths)):
            if not np.allclose(a[-1], b[0], atol=1e-9):
                raise TimingError(f"paths {i} and {i + 1} do not join: a path must start where the previous one ends")
        return out

    def _pieces(self, steps: Sequence[Step], velocities: list[np.ndarray], rest: list[list], slow: list) -> list[Piece]:
        """Ruckig segments and gripper holds in order; rest[p][i] is path p's segment i timed rest-to-rest, and
        slow[p][i] the extra limit scale of its blended version."""
        pieces: list[Piece] = []
        q_last = None
        paths = iter(enumerate(velocities))
        for step in steps:
            if isinstance(step, GripperAction):
                pieces.append(_Hold(q_last, step.duration_s, step))
                continue
            p, v = next(paths)
            for i in range(len(step) - 1):
                traj, scale = rest[p][i]
                if np.any(v[i : i + 2]):
                    try:
                        traj = self.blended_segment(step[i], v[i], step[i + 1], v[i + 1], scale * slow[p][i])
                    except _TooFast as e:
                        raise _Unblendable(p, i, e.factor) from e
                    except (TimingError, RuckigError) as e:
                        raise _Unblendable(p, i, 0.0) from e
                pieces.append(traj)
            q_last = step[-1]
        if not pieces:  # a single-waypoint path: hold it for one period
            pieces.append(_Hold(steps[0][0], 0.0, GripperAction("wait", 0.0)))
        return pieces

    def _sample(self, pieces: Sequence[Piece]) -> tuple[JointTrajectory, np.ndarray]:
        """Sample the chain at k * dt (the last sample is the final position at rest); also return each piece's
        start time."""
        dt = self.dt
        starts = np.concatenate([[0.0], np.cumsum([p.duration for p in pieces])])
        n = int(np.ceil(starts[-1] / dt - 1e-9)) + 1
        t = np.minimum(np.arange(n) * dt, starts[-1])
        owner = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
        q = np.empty((n, self.limits.dof))
        events = []
        for i, piece in enumerate(pieces):
            mask = owner == i
            if isinstance(piece, _Hold):
                q[mask] = piece.q
                a = piece.event
                if a.duration_s > 0 or a.kind != "wait":
                    events.append(GripperEvent(float(starts[i]), a.kind, a.width_m, a.duration_s))
            else:
                for k in np.flatnonzero(mask):
                    q[k] = piece.at_time(t[k] - starts[i])[0]
        last = pieces[-1]
        q[-1] = last.q if isinstance(last, _Hold) else last.at_time(last.duration)[0]
        return JointTrajectory(self.joint_names, dt, q, tuple(events)), starts

    def _outside_limits(self, traj: JointTrajectory) -> list[float]:
        q = traj.positions
        return list(traj.times[np.any((q < self.limits.lower) | (q > self.limits.upper), axis=1)])


def _owners(steps: Sequence[Step]) -> list[tuple[int, int] | None]:
    """(path, segment) of every piece in order; None for gripper holds."""
    owners: list[tuple[int, int] | None] = []
    p = -1
    for s in steps:
        if isinstance(s, GripperAction):
            owners.append(None)
        else:
            p += 1
            owners += [(p, k) for k in range(len(s) - 1)]
    return owners
