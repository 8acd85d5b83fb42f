"""What the run loop hands to its stages, and how a stage says no.

A stage reads what earlier stages left in the `RunContext`, adds its own result, records what it decided in its
section of the run's summary and raises `StageError` (a refusal, with a reason a person can read) when the run
must not go on.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Protocol

from drivers.types import RGBDFrame
from motion.executor import Executor
from motion.manipulation.phases import ManipulationPlan
from motion.report import ExecutionReport
from pipeline.contact.clouds import SceneClouds
from pipeline.contact.types import ContactPlan
from pipeline.grounding.types import ObjectMotion
from pipeline.reasoning.types import GoalState
from runtime.config import Profile
from runtime.devices import Devices
from runtime.messaging.messages import PlanSummary
from runtime.run.record import RunRecord
from runtime.run.summary import LookRecord, Verification


class StageError(RuntimeError):
    """The stage refuses to continue; the message is the run's FAILED reason."""


@dataclass
class RunContext:
    profile: Profile
    devices: Devices
    instruction: str
    record: RunRecord
    cancel: threading.Event
    frame0: RGBDFrame | None = None  # the capture the plan is made from (the first, or a second look's)
    basis: str = "capture"  # frame0's name in the run folder
    goal: GoalState | None = None  # reasoning
    motion: ObjectMotion | None = None  # grounding (ok)
    clouds: SceneClouds | None = None  # planning: the target's and the scene's points (base frame)
    contact: ContactPlan | None = None  # the contact the plan uses
    manipulation: ManipulationPlan | None = None  # its gate-approved phases
    plan: PlanSummary | None = None  # what the operator confirms
    frame1: RGBDFrame | None = None  # the capture after execution
    executor: Executor | None = None  # streaming the phases, while execution runs
    executed: list[tuple[str, ExecutionReport]] = field(default_factory=list)  # (phase, its report), as streamed
    executing: bool = False  # the run reached EXECUTING: a run that ends badly from here must stop the motion


class Stages(Protocol):
    """One method per pipeline state; each may take long, none may command the arm outside `execute`."""

    def capture(self, ctx: RunContext) -> None: ...

    def reason(self, ctx: RunContext) -> None: ...

    def ground(self, ctx: RunContext) -> None: ...

    def plan(self, ctx: RunContext) -> PlanSummary: ...

    def recheck(self, ctx: RunContext) -> LookRecord:
        """The second look right before moving; may re-base ctx on the look (see runtime.run.second_look)."""
        ...

    def execute(self, ctx: RunContext) -> None: ...

    def verify(self, ctx: RunContext) -> Verification: ...

    def stop_motion(self, ctx: RunContext, reason: str, graceful: bool) -> None:
        """The run ended during or after EXECUTING: end the motion. graceful (operator abort): come to rest on
        the path, returning once at rest (bounded); otherwise the arm was already stopped: stop streaming."""
        ...
