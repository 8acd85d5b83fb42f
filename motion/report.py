"""What the executor reports: outcome, timing quality, tracking, gripper results and the streamed log."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from safety.trajectory import GripperEvent

Status = Literal["completed", "aborted", "estopped", "fault"]


@dataclass(frozen=True)
class GripperOutcome:
    event: GripperEvent
    width_m: float | None = None  # measured at the end of a close
    grasped: bool | None = None  # close only: fingers stopped on something


@dataclass(frozen=True)
class Jitter:
    """|actual tick period - nominal| [s]."""

    p50_s: float
    p99_s: float
    max_s: float

    @classmethod
    def of(cls, wake_times: list[float], period: float) -> Jitter:
        if len(wake_times) < 2:
            return cls(0.0, 0.0, 0.0)
        err = np.abs(np.diff(wake_times) - period)
        return cls(float(np.percentile(err, 50)), float(np.percentile(err, 99)), float(err.max()))


@dataclass(frozen=True)
class ExecutionReport:
    status: Status
    reason: str
    ticks: int
    late_ticks: int  # driver calls that overran into a later tick
    jitter: Jitter
    max_tracking_error_rad: float  # measured position vs the nearest set-point of the last tracking_lag_s
    realtime_priority: bool  # the streaming thread ran with SCHED_FIFO (else jitter depends on the machine load)
    max_step_rad: float  # largest set-point change actually sent
    gripper: tuple[GripperOutcome, ...]
    times_s: np.ndarray = field(repr=False)  # clock time of each tick
    tau_s: np.ndarray = field(repr=False)  # trajectory time commanded at each tick
    q_cmd: np.ndarray = field(repr=False)  # (ticks, dof) set-points sent
    q_meas: np.ndarray = field(repr=False)  # (ticks, dof) measured at the start of each tick
