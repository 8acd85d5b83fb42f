"""The `motion` section of a profile: how paths are searched and timed (the safety limits stay in `safety`)."""

from __future__ import annotations

from pydantic import Field

from drivers.config import StrictModel
from motion.planner import PlannerConfig, PlannerName


class MotionConfig(StrictModel):
    """Planner choice and budget, a speed fraction of the safety limits, and whether free moves blend."""

    planner: PlannerName = Field(default="RRTConnect", description="OMPL planner for free-space moves")
    planning_timeout_s: float = Field(default=1.0, gt=0, le=30, description="search budget per attempt")
    planning_attempts: int = Field(default=3, ge=1, le=20, description="fresh searches before giving up")
    speed_scale: float = Field(
        default=1.0, gt=0, le=1, description="fraction of the safety velocity/acceleration/jerk limits used to time"
    )
    push_tcp_speed_m_s: float = Field(
        default=0.1,
        gt=0,
        le=1.0,
        description="TCP speed limit of a straight push: a faster one throws the object on past where the fingers "
        "stop, or tips it",
    )
    blend_free_moves: bool = Field(
        default=True,
        description="cross the interior waypoints of free-space moves (approach, home) without stopping, where the "
        "gate accepts the bent path; straight lines into and out of contact always stop at their ends",
    )

    def planner_config(self) -> PlannerConfig:
        return PlannerConfig(planner=self.planner, timeout_s=self.planning_timeout_s, attempts=self.planning_attempts)
