"""summary.json: what one run decided, as one pydantic model with a versioned schema.

Every stage fills its own section; the record writes the whole model when the run ends, so the file always has
this shape (SCHEMA_VERSION, documented in the README). Bump SCHEMA_VERSION when a field changes meaning or goes.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from motion.report import ExecutionReport
from pipeline.grounding.compare import Comparison
from pipeline.grounding.types import ObjectMotion
from runtime.messaging.messages import PlanSummary

SCHEMA_VERSION = 2  # 2: the second look before moving (second_look), a state RECHECKING among the transitions


class Section(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=True)


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


class ReasoningRecord(Section):
    target: str
    prompt: str
    validated: bool
    iterations: int
    seconds: dict[str, float]


class MotionRecord(Section):
    """A grounded motion as `goalvla ground` writes it (x_goal = R x_init + t, camera frame), plus the base frame."""

    ok: bool
    reason: str
    R: list[list[float]]
    t: list[float]
    scale: float
    inliers: int
    matches: int
    confidence: float
    residual_m: float | None
    depth_residual_m: float | None
    T_base_motion: list[list[float]] | None = None  # with a calibration, when ok
    translation_base_m: list[float] | None = None
    adjusted: str | None = None  # why the registration's motion was changed (see ADJUSTMENTS)
    symmetry: str | None = None  # the turns the images cannot show (pipeline.grounding.seen_symmetry), when ok

    @classmethod
    def of(cls, motion: ObjectMotion) -> MotionRecord:
        T_base = motion.T_base if motion.ok and motion.T_base_camera is not None else None
        return cls(
            ok=motion.ok,
            reason=motion.reason,
            R=np.asarray(motion.R).tolist(),
            t=np.asarray(motion.t).tolist(),
            scale=float(motion.scale),
            inliers=int(motion.inliers),
            matches=int(motion.matches),
            confidence=float(motion.confidence),
            residual_m=_finite(motion.residual_m),
            depth_residual_m=_finite(motion.depth_residual_m),
            T_base_motion=None if T_base is None else T_base.tolist(),
            translation_base_m=None if T_base is None else T_base[:3, 3].tolist(),
            adjusted="; ".join(motion.details[k] for k in ADJUSTMENTS if k in motion.details) or None,
            symmetry=motion.symmetry.label if motion.symmetry is not None else None,
        )


# ObjectMotion.details keys: why it was changed
ADJUSTMENTS = ("turned_end_for_end", "stood_straight", "kept_level", "settled")


class ContactRecord(Section):
    mode: str
    # a push carried instead (pipeline.contact carry_when_no_push): why no push could be made
    carried_because: str | None = None
    candidates: int
    plans: int
    rejected: dict[str, int]  # why candidates were ruled out, with how many each reason ruled out
    # per ranked plan, how far its object motion turns from the grounded one (a body of revolution may be set down
    # turned about its own axis, the same goal to the eye); 0 = as grounded
    turn_from_grounded_deg: list[float]


class PlanningRecord(Section):
    contact_used: str | None = None  # the contact whose manipulation planned and passed the gate
    refusals: list[str] = Field(default_factory=list)  # why the contacts tried before it could not be planned


class ChangeRecord(Section):
    """A region of the scene whose depth changed between the capture the plan was made from and a second look."""

    what: Literal["target", "scene"]  # on the target (where it was or is now), or anywhere else
    area_cm2: float
    max_change_mm: float
    at_base_m: list[float]  # its centre, base frame


class LookRecord(Section):
    """One second look right before moving, and what the run did about it."""

    capture: str  # the look's capture in the run folder (look1.png, look1.npz)
    compared_with: str  # the capture the plan was made from
    changes: list[ChangeRecord]
    target_shift_m: float | None = None  # the target's measured motion since, when its depth changed
    target_turn_deg: float | None = None  # (a turn its symmetry hides is not counted)
    drift: MotionRecord | None = None  # that measurement (grounding's registration; absent for a ball)
    # still: execute the confirmed plan; replan: the target alone moved, its motion re-based on this look and
    # planned again; reason: something else moved (or the target cannot be measured), everything from the goal
    # image on is made again from this look
    decision: Literal["still", "replan", "reason"]
    reason: str
    seconds: float


class ConfirmationRecord(Section):
    source: str
    approved: bool


class GripperRecord(Section):
    kind: str
    width_m: float | None
    grasped: bool | None


class PhaseRecord(Section):
    phase: str
    status: str
    reason: str
    ticks: int
    late_ticks: int
    jitter_p99_s: float
    max_tracking_error_rad: float
    gripper: list[GripperRecord]

    @classmethod
    def of(cls, phase: str, report: ExecutionReport) -> PhaseRecord:
        return cls(
            phase=phase,
            status=report.status,
            reason=report.reason,
            ticks=report.ticks,
            late_ticks=report.late_ticks,
            jitter_p99_s=report.jitter.p99_s,
            max_tracking_error_rad=report.max_tracking_error_rad,
            gripper=[GripperRecord(kind=g.event.kind, width_m=g.width_m, grasped=g.grasped) for g in report.gripper],
        )


class AchievedRecord(Section):
    """How the achieved motion was measured: a registration between the captures (refused: its reason), a ball's
    centre shift, or not at all (`none`, with the reason: the target not found again, the camera moved)."""

    method: Literal["registration", "ball_centre", "none"]
    registration: MotionRecord | None = None
    ball_centre_shift_m: list[float] | None = None
    reason: str = ""


class GroupCountRecord(Section):
    """A sweep's verification: the parts counted inside the container after it, of those seen before."""

    total: int
    inside: int
    outside: int
    required: int


class LiftCheckRecord(Section):
    """A lift's verification: how the object's seen points rose, against the goal."""

    lowest_rise_m: float  # its lowest seen point
    centre_rise_m: float  # its seen centre
    goal_rise_m: float
    error_m: float  # seen centre to the goal's


class LaidCheckRecord(Section):
    """A flat object laid on its face (let go on its edge to tip over): how it lies, against the goal."""

    top_m: float  # its seen top above the table
    thickness_m: float  # its thinnest extent as first seen
    error_m: float  # seen middle to the goal's, across the table


class StoodCheckRecord(Section):
    """A body of revolution stood up, judged by its axis when no registration relates its lying and standing views."""

    tilt_deg: float  # its axis after execution off the goal's
    error_m: float  # its axis after execution to the goal's, across the table


class Verification(Section):
    ok: bool
    reason: str
    comparison: Comparison | None = None  # absent when no achieved motion could be compared
    group_count: GroupCountRecord | None = None  # a sweep's parts counted in the container
    lift: LiftCheckRecord | None = None  # a lift's rise
    lid_tilt_deg: float | None = None  # a close: the lid's seen face off the table's plane after execution
    laid: LaidCheckRecord | None = None  # a flat object laid on its face
    stood: StoodCheckRecord | None = None  # a body of revolution stood up, judged by its axis


class TaskTruthRecord(Section):
    """What the task itself asks, judged from the simulator: a sweep's parts inside the container's floor, an
    object lifted clear of everything but the fingers, a support left empty with the object on the table."""

    action: str  # sweep, lift, take_off, stand_up
    done: bool  # the task is done by the simulator's measure
    detail: str
    parts_inside: int | None = None  # sweep
    parts_total: int | None = None
    lifted_m: float | None = None  # lift, take_off: how far the object's lowest point is above the table
    touching: list[str] = Field(default_factory=list)  # what the object touches (besides the fingers)


class SimTruthRecord(Section):
    """The simulator's truth, for benchmarks only (never used to decide success)."""

    object_displacement_m: dict[str, float]  # how far each object's centre moved
    hinge_deg: dict[str, float]  # each hinge joint's angle after the run
    target: str | None = None  # a whole object that was moved: the one that moved most
    target_goal_error_m: float | None = None  # how far its centre ended from where the goal motion puts it
    # how far it is turned from the goal motion's turn, up to the turns its shape does not show (a ball's, a
    # cylinder's about its axis, a cube's quarter turns)
    target_turn_error_deg: float | None = None
    target_tilt_error_deg: float | None = (
        None  # ... and tipped from the goal's pose (a turn about the vertical is none)
    )
    task: TaskTruthRecord | None = None  # the truth of a sweep, a lift or a take-off


class TransitionRecord(Section):
    previous: str
    state: str
    reason: str
    stamp_s: float


class RunSummary(Section):
    schema_version: Literal[2] = SCHEMA_VERSION
    run_id: str
    status: Literal["RUNNING", "DONE", "FAILED", "ESTOPPED"] = "RUNNING"
    reason: str = ""
    instruction: str = ""
    profile: str = ""
    robot_id: str = ""
    scene: str | None = None  # sim profiles
    seed: int | None = None
    stage_seconds: dict[str, float] = Field(default_factory=dict)
    reasoning: ReasoningRecord | None = None
    object_motion: MotionRecord | None = None
    contact: ContactRecord | None = None
    planning: PlanningRecord | None = None
    plan: PlanSummary | None = None
    confirmation: ConfirmationRecord | None = None
    second_look: list[LookRecord] = Field(default_factory=list)  # in order; the last one let the run move
    execution: list[PhaseRecord] = Field(default_factory=list)
    achieved_motion: AchievedRecord | None = None
    verification: Verification | None = None
    sim_truth: SimTruthRecord | None = None
    wall_s: float | None = None
    # seconds spent after the run's end on its record: trajectories, plots, recording (run.rrd), report
    record_seconds: dict[str, float] = Field(default_factory=dict)
    transitions: list[TransitionRecord] = Field(default_factory=list)
    images: list[str] = Field(default_factory=list)  # <name>.png in the run folder
