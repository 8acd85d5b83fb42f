"""Contact planning settings and results."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from pydantic import Field

from drivers.config import StrictModel
from safety.geometry import Primitive

ContactMode = Literal["grasp", "push", "hinge"]


class ContactConfig(StrictModel):
    """Sampling, filtering and scoring of contact poses (lengths in metres, angles in degrees)."""

    yaw_step_deg: float = Field(default=15.0, ge=1, le=90, description="closing-axis step of the grasp sweep")
    side_approach_deg: tuple[float, ...] = Field(default=(-30.0, 0.0, 30.0), max_length=12)
    lean_deg: float = Field(
        default=20.0,
        ge=0,
        le=45,
        description="grasps from above also lean this far each way about the closing axis (the pads stay on the "
        "same faces), the wrist away from a tall neighbour in front of or behind the fingers; 0: straight down only",
    )
    finger_clearance_m: float = Field(default=0.008, ge=0, description="free gap kept each side when opening")
    min_finger_clearance_m: float = Field(
        default=0.004,
        ge=0,
        description="the least free gap each side for an object too wide for finger_clearance_m: the fingers open "
        "fully and the collision checks judge the descent",
    )
    squeeze_m: float = Field(default=0.02, ge=0, description="commanded width below the object's width")
    grasp_depth_m: float = Field(default=0.04, gt=0, description="how far the TCP goes below the object top")
    min_tcp_height_m: float = Field(default=0.012, ge=0, description="lowest TCP height above the table")
    max_tilt_deg: float = Field(default=100.0, gt=0, le=180, description="cone: approach axis vs straight down")
    pre_distance_m: float = Field(default=0.10, gt=0, description="pre-contact pose backed off along the approach")
    push_standoff_m: float = Field(
        default=0.015, ge=0, description="push: the closed fingers' front this far behind the object to start"
    )
    push_tilt_deg: float = Field(
        default=15.0, ge=0, le=60, description="push: the hand tilted back so only the fingertips touch, low"
    )
    carry_when_no_push: bool = Field(
        default=True,
        description="push: when no push can be made (no room behind the object), pick the object up and set it "
        "down where the push would have left it",
    )
    hinge_contact_fraction: float = Field(
        default=0.8, gt=0, le=1, description="arc push: contact this far out from the hinge, part extent = 1"
    )
    hinge_step_deg: float = Field(default=10.0, ge=1, le=45, description="arc push: largest turn between via poses")
    hinge_approach_deg: float = Field(
        default=25.0, ge=0, le=90, description="arc push: approach line's slant off the part's face, 0 = along it"
    )
    hinge_end_max_gap_m: float = Field(
        default=0.04,
        ge=0.012,
        description="arc push: the fingers end at most this far off the part's face at the goal (the least the "
        "scene's clearance allows)",
    )
    hinge_max_slide_m: float = Field(default=0.005, ge=0, description="hinge motion: largest slide along the axis")
    hinge_min_turn_deg: float = Field(default=5.0, ge=0, description="hinge motion: smallest turn worth a push")
    collision_padding_m: float = Field(default=0.005, ge=0)
    place_lifts_m: tuple[float, ...] = Field(
        default=(),
        max_length=10,
        description="grasp: heights above the goal pose the gripper passes setting the object down",
    )
    max_drop_m: float = Field(
        default=0.08,
        ge=0,
        le=0.2,
        description="grasp: how much higher than place_lifts_m[0] the object may be let go where the gripper would "
        "touch the scene lower (a container's walls, a neighbour): the object drops the rest",
    )
    placed_clearance_m: float = Field(default=0.004, ge=0, description="moved object vs other scene points")
    ik_candidates: int = Field(
        default=12, ge=1, le=200, description="best geometric candidates checked for reachability"
    )
    keep: int = Field(default=5, ge=1, le=50, description="reachable plans returned")
    weights: dict[str, float] = Field(
        default_factory=lambda: {"antipodal": 1.0, "centred": 0.7, "approach": 0.5, "reach": 0.5}
    )


@dataclass(frozen=True, kw_only=True)
class ContactPlan:
    """One contact decision, from contact planning to execution: TCP poses in the base frame (TCP z = approach
    direction, y = closing axis) and the joints they were solved with in the gate's scene, which the manipulation
    plans from and checks in each phase's world instead of solving them again."""

    mode: ContactMode
    T_pre: np.ndarray  # approach start
    T_contact: np.ndarray  # grasp pose, or where the push starts
    T_goal: np.ndarray  # T_contact carried by the object motion (grasp, push); the arc's end (hinge)
    # the object motion the plan realises (x_goal = T x_init, base frame): the one asked for, or for a body of
    # revolution that goal turned about the body's own axis (the same to the eye)
    T_motion: np.ndarray
    width_m: float  # finger gap to command at contact (grasp: below the object's width; push: closed)
    open_width_m: float  # finger gap on the approach and at the pre-contact and contact poses (IK checked at it)
    # grasp: finger gap opened to let go: as wide as the scene at the release allows, at least open_width_m (the
    # measured width a partial cloud gives is often below the object's, and fingers left touching it drag it along
    # on the way out); push: open_width_m
    release_width_m: float
    object_width_m: float  # measured gap the object needs between the fingers (0 for pushes)
    q_pre: np.ndarray
    q_contact: np.ndarray
    q_goal: np.ndarray
    via: tuple[np.ndarray, ...] = ()  # TCP poses between contact and goal, in order (hinge: along the arc)
    q_via: tuple[np.ndarray, ...] = ()
    # grasp: the poses above T_goal the object is set down from (ContactConfig.place_lifts_m), lowest first
    T_place: tuple[np.ndarray, ...] = ()
    q_place: tuple[np.ndarray, ...] = ()
    # grasp: the pose the object is set down from when it is not T_goal (q_goal is its joints): a flat object laid
    # on its face is let go standing on its far edge and tips over onto its goal (tipping.py)
    T_set: np.ndarray | None = None
    held: Primitive | None = None  # grasp: the object's geometry in the TCP frame once grasped
    score: float = 0.0
    scores: dict[str, float] = field(default_factory=dict)
    source: str = "pipeline.contact"  # who decided (for the record), e.g. "pipeline.contact #1 score 0.82"


@dataclass(frozen=True)
class ContactResult:
    """Ranked plans (best first) and how many candidates each filter rejected."""

    plans: list[ContactPlan]
    rejected: dict[str, int] = field(default_factory=dict)
    candidates: int = 0

    @property
    def ok(self) -> bool:
        return bool(self.plans)

    @property
    def best(self) -> ContactPlan:
        if not self.plans:
            raise ValueError(f"no feasible contact: {self.reason}")
        return self.plans[0]

    @property
    def reason(self) -> str:
        """Why nothing was found (empty when plans exist): the rejection counts, largest first."""
        if self.plans:
            return ""
        parts = [f"{n} {why}" for why, n in sorted(self.rejected.items(), key=lambda kv: -kv[1])]
        return f"all {self.candidates} candidates rejected: " + (", ".join(parts) or "no candidate sampled")
