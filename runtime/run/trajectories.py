"""The run's motion as data: each phase's planned (gate-approved) trajectory, what was streamed and measured, the
joint limits they were held to and the robot's clearance from the scene along the plan.

Taken from the run context when the run ends (references only; nothing is computed while the arm moves) and
kept in the run folder as `trajectories.npz`, from which the report's plots and the Rerun recording are drawn, so
both can be made again from the folder alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from motion.limits import MotionLimits

if TYPE_CHECKING:  # the context holds the record, which writes this file
    from runtime.run.context import RunContext

FILE = "trajectories.npz"


@dataclass(frozen=True)
class PlannedPhase:
    name: str
    dt: float  # [s]
    positions: np.ndarray  # (N, dof) [rad], sample k at k * dt from the phase's start
    gate_ok: bool
    gate_samples: int  # trajectory samples the gate checked
    gate_configurations: int  # collision checks, sub-samples between samples included
    gate_seconds: float
    # (M, 2): trajectory time [s] and the robot's clearance from the scene there [m] (runtime.run.clearance)
    clearance: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def times(self) -> np.ndarray:
        return np.arange(len(self.positions)) * self.dt

    @property
    def velocities(self) -> np.ndarray:
        """Backward differences, at rest before the first sample (as the gate computes them) [rad/s]."""
        q = np.vstack([self.positions[:1], self.positions])
        return np.diff(q, axis=0) / self.dt


@dataclass(frozen=True)
class ExecutedPhase:
    name: str
    status: str
    start_s: float  # first tick, from the first phase's first tick [s]
    times_s: np.ndarray  # tick times from the phase's first tick [s]
    tau_s: np.ndarray  # trajectory time commanded at each tick [s]
    q_cmd: np.ndarray  # (ticks, dof) set-points sent [rad]
    q_meas: np.ndarray  # (ticks, dof) measured at each tick [rad]

    def tracking_error_rad(self, lag_s: float) -> np.ndarray:
        """Per tick, as the executor measures it: the largest joint's distance of the measured position from the
        nearest of the set-points sent in the last lag_s (the state trails the commands)."""
        if len(self.q_cmd) < 2:
            return np.zeros(len(self.q_cmd))
        period = float(np.median(np.diff(self.times_s)))
        lag = max(1, round(lag_s / period)) if period > 0 else 1
        err = np.full(len(self.q_cmd), np.inf)
        for back in range(lag + 1):
            shifted = np.vstack([np.repeat(self.q_cmd[:1], back, axis=0), self.q_cmd[: len(self.q_cmd) - back]])
            err = np.minimum(err, np.abs(self.q_meas - shifted).max(axis=1))
        return err


@dataclass(frozen=True)
class RunTrajectories:
    joint_names: tuple[str, ...]
    lower: np.ndarray  # [rad]
    upper: np.ndarray
    velocity_limit: np.ndarray  # [rad/s], the profile's (never above the vendor's)
    planned: tuple[PlannedPhase, ...]
    executed: tuple[ExecutedPhase, ...]

    @classmethod
    def of(cls, ctx: RunContext, limits: MotionLimits, joint_names: tuple[str, ...]) -> RunTrajectories:
        planned = ()
        if ctx.manipulation is not None:
            planned = tuple(
                PlannedPhase(
                    name=name,
                    dt=float(a.trajectory.dt),
                    positions=np.asarray(a.trajectory.positions),
                    gate_ok=a.report.ok,
                    gate_samples=a.report.samples,
                    gate_configurations=a.report.configurations_checked,
                    gate_seconds=float(a.report.seconds),
                )
                for name, a in zip(ctx.manipulation.phase_names, ctx.manipulation.phases, strict=True)
            )
        executed = []
        t0 = next((float(r.times_s[0]) for _, r in ctx.executed if len(r.times_s)), 0.0)
        for name, r in ctx.executed:
            start = float(r.times_s[0]) if len(r.times_s) else t0
            executed.append(
                ExecutedPhase(
                    name=name,
                    status=r.status,
                    start_s=start - t0,
                    times_s=np.asarray(r.times_s) - start,
                    tau_s=np.asarray(r.tau_s),
                    q_cmd=np.asarray(r.q_cmd),
                    q_meas=np.asarray(r.q_meas),
                )
            )
        return cls(
            joint_names=tuple(joint_names),
            lower=np.asarray(limits.lower, float),
            upper=np.asarray(limits.upper, float),
            velocity_limit=np.asarray(limits.velocity, float),
            planned=planned,
            executed=tuple(executed),
        )

    def with_clearance(self, clearances: list[np.ndarray]) -> RunTrajectories:
        phases = tuple(
            PlannedPhase(**{**p.__dict__, "clearance": np.asarray(c, float).reshape(-1, 2)})
            for p, c in zip(self.planned, clearances, strict=True)
        )
        return RunTrajectories(**{**self.__dict__, "planned": phases})

    @property
    def empty(self) -> bool:
        return not self.planned and not self.executed

    # -- the file -----------------------------------------------------------------------------------------
    def save(self, run_dir: Path) -> Path:
        arrays: dict[str, np.ndarray] = {
            "joint_names": np.array(self.joint_names),
            "lower": self.lower,
            "upper": self.upper,
            "velocity_limit": self.velocity_limit,
            "planned": np.array([p.name for p in self.planned]),
            "executed": np.array([e.name for e in self.executed]),
        }
        for i, p in enumerate(self.planned):
            arrays[f"planned_{i}_positions"] = p.positions
            arrays[f"planned_{i}_clearance"] = p.clearance
            arrays[f"planned_{i}_gate"] = np.array(
                [p.dt, p.gate_ok, p.gate_samples, p.gate_configurations, p.gate_seconds], float
            )
        for i, e in enumerate(self.executed):
            for key in ("times_s", "tau_s", "q_cmd", "q_meas"):
                arrays[f"executed_{i}_{key}"] = getattr(e, key)
            arrays[f"executed_{i}_status"] = np.array([e.status])
            arrays[f"executed_{i}_start_s"] = np.array([e.start_s])
        path = run_dir / FILE
        np.savez_compressed(path, **arrays)
        return path

    @classmethod
    def load(cls, run_dir: Path) -> RunTrajectories | None:
        """The run's trajectories, or None when the run left none (it ended before planning, or predates them)."""
        path = run_dir / FILE
        if not path.is_file():
            return None
        with np.load(path, allow_pickle=False) as z:
            planned = []
            for i, name in enumerate(z["planned"].tolist()):
                dt, ok, samples, configs, seconds = z[f"planned_{i}_gate"].tolist()
                planned.append(
                    PlannedPhase(
                        name=name,
                        dt=dt,
                        positions=z[f"planned_{i}_positions"],
                        gate_ok=bool(ok),
                        gate_samples=int(samples),
                        gate_configurations=int(configs),
                        gate_seconds=seconds,
                        clearance=z[f"planned_{i}_clearance"],
                    )
                )
            executed = [
                ExecutedPhase(
                    name=name,
                    status=str(z[f"executed_{i}_status"][0]),
                    start_s=float(z[f"executed_{i}_start_s"][0]),
                    times_s=z[f"executed_{i}_times_s"],
                    tau_s=z[f"executed_{i}_tau_s"],
                    q_cmd=z[f"executed_{i}_q_cmd"],
                    q_meas=z[f"executed_{i}_q_meas"],
                )
                for i, name in enumerate(z["executed"].tolist())
            ]
            return cls(
                joint_names=tuple(z["joint_names"].tolist()),
                lower=z["lower"],
                upper=z["upper"],
                velocity_limit=z["velocity_limit"],
                planned=tuple(planned),
                executed=tuple(executed),
            )
