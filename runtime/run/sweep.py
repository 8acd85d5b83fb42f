"""The planning stage of a sweep: the group, the tool and the container from the capture, swept by
pipeline.contact.sweep, phased and gate-approved by motion.manipulation.sweep, recorded."""

from __future__ import annotations

import numpy as np

from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.phases import ManipulationPlan
from motion.manipulation.sweep import plan_sweep_phases
from pipeline.contact.clouds import SceneClouds, scene_clouds
from pipeline.contact.sweep import SweepPlan, SweepRefused, plan_sweep
from runtime.run.contact import contact_config
from runtime.run.context import RunContext, StageError
from runtime.run.summary import ContactRecord, PlanningRecord
from safety.geometry import transform_points
from safety.robot_model import RobotModel

PLAN_ATTEMPTS = 2  # OMPL is randomised: a free path missed once may be found on a retry


def _points(ctx: RunContext, mask: np.ndarray) -> np.ndarray:
    frame = ctx.frame0
    valid = mask & np.isfinite(frame.depth)
    return transform_points(frame.T_base_camera, frame.intrinsics.unproject_depth_image(frame.depth)[valid])


def plan_sweep_stage(ctx: RunContext, robot: RobotModel, q_start: np.ndarray) -> tuple[SweepPlan, ManipulationPlan]:
    """The sweep's plan and its approved phases; StageError with the reason when the group cannot be swept."""
    goal, profile = ctx.goal, ctx.profile
    if goal.mask_tool is None or goal.mask_reference is None:
        raise StageError(f"sweep: reasoning named no tool ({goal.tool!r}) or no container ({goal.reference!r})")
    clouds = scene_clouds(
        ctx.frame0, goal.mask_init | goal.mask_tool, robot, q_start, workspace=profile.safety.workspace
    )
    group, tool = _points(ctx, goal.mask_init), _points(ctx, goal.mask_tool)
    ctx.clouds = SceneClouds(target=group, scene=clouds.scene)  # what the record draws: the group moves, not the tool
    try:
        contact = plan_sweep(
            group,
            tool,
            _points(ctx, goal.mask_reference),
            clouds.scene,
            ctx.motion.T_base,
            robot,
            contact=contact_config(ctx, robot),
            safety_config=profile.safety,
            q_seed=q_start,
            viewpoint=ctx.frame0.T_base_camera[:3, 3],
            tool_name=goal.tool or "tool",
        )
    except SweepRefused as e:
        ctx.record.summary.contact = ContactRecord(
            mode="sweep", candidates=0, plans=0, rejected={str(e): 1}, turn_from_grounded_deg=[]
        )
        raise StageError(f"cannot sweep: {e}") from e
    ctx.record.summary.contact = ContactRecord(
        mode="sweep",
        candidates=len(contact.strokes),
        plans=1,
        rejected=contact.rejected,
        turn_from_grounded_deg=[0.0],
    )
    chain = ManipulationChain(
        robot,
        robot_config=profile.robot,
        safety=profile.safety,
        motion=profile.motion,
        q_start=q_start,
        scene=clouds.scene,
        target=group,
    )
    refusals = []
    for _ in range(PLAN_ATTEMPTS):
        try:
            manipulation = plan_sweep_phases(chain, contact, tool)
            break
        except ManipulationRefused as e:
            refusals.append(f"{contact.source}: {e}")
    else:
        ctx.record.summary.planning = PlanningRecord(refusals=refusals)
        raise StageError("the sweep could not be planned:\n  " + "\n  ".join(refusals))
    source = f"{contact.source}: {len(contact.strokes)} stroke(s), grasp score {contact.score:.2f}"
    ctx.record.summary.planning = PlanningRecord(contact_used=source, refusals=refusals)
    return contact, manipulation
