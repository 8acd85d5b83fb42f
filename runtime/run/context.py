"""What the run loop hands to its stages, and how a stage says no.

A stage reads what earlier stages left in the `RunContext`, adds its own result, records what it decided and
raises `StageError` (a refusal, with a reason a person can read) when the run must not go on.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any, Protocol

from runtime.config import Profile
from runtime.devices import Devices
from runtime.messaging.messages import PlanSummary
from runtime.run.record import RunRecord


class StageError(RuntimeError):
    """The stage refuses to continue; the message is the run's FAILED reason."""


class StageUnavailable(StageError):
    """The module a stage needs is not part of this build (or failed to import); never a silent success."""


@dataclass
class Verification:
    ok: bool
    reason: str
    position_error_m: float | None = None
    rotation_error_deg: float | None = None
    details: dict = field(default_factory=dict)


@dataclass
class RunContext:
    profile: Profile
    devices: Devices
    instruction: str
    record: RunRecord
    cancel: threading.Event
    frame0: Any = None  # RGBDFrame before the run
    goal: Any = None  # GoalState from reasoning
    motion: Any = None  # ObjectMotion from grounding
    contact: Any = None  # ContactPlan
    trajectory: Any = None  # the gate-approved trajectory
    plan: PlanSummary | None = None
    frame1: Any = None  # RGBDFrame after execution
    extras: dict = field(default_factory=dict)  # stage-private hand-over (e.g. the executor while it runs)


class Stages(Protocol):
    """One method per pipeline state; each may take long, none may command the arm outside `execute`."""

    def capture(self, ctx: RunContext) -> None: ...

    def reason(self, ctx: RunContext) -> None: ...

    def ground(self, ctx: RunContext) -> None: ...

    def plan(self, ctx: RunContext) -> PlanSummary: ...

    def execute(self, ctx: RunContext) -> None: ...

    def verify(self, ctx: RunContext) -> Verification: ...

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        """The run ended during or after EXECUTING: end the motion. graceful (operator abort): come to rest on
        the path, returning once at rest (bounded); otherwise the arm was already stopped: stop streaming."""
        ...
