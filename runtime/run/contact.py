"""The contact stage of a run: pipeline.contact asked for what the manipulation can do, its plans recorded.

What the run adds is the question: the mode the instruction asks for, the target's and the scene's points, and
settings that propose only what the gate can pass (the gripper grown by the gate's padding clears the table and
the scene; a grasp's set-down heights are the manipulation's, motion.manipulation.phases.place_heights).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from motion.manipulation.phases import place_heights
from pipeline.contact.clouds import SceneClouds
from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.planner import plan_contacts
from pipeline.contact.symmetry import turn_deg
from pipeline.contact.types import ContactConfig, ContactMode, ContactPlan, ContactResult
from pipeline.reasoning.instruction import parse_instruction
from runtime.run.context import RunContext, StageError
from runtime.run.summary import ContactRecord
from safety.collision import CollisionWorld
from safety.robot_model import RobotModel

MODES: dict[str, ContactMode] = {"push": "push", "close": "hinge"}  # instruction action -> mode (else: grasp)
TABLE_MARGIN_M = 0.002
PUTS_DOWN = ("place", "take_off")  # actions that carry their object elsewhere without turning it over
COMES_TO_REST = ("place", "stand_up", "take_off")  # actions that set their object down (a turn in place does not)


def contact_mode(instruction: str) -> ContactMode:
    """push for the grammar's push sentences, hinge (an arc push about the part's hinge) for close, grasp otherwise
    (free text from a model backend included)."""
    try:
        action = parse_instruction(instruction).action
    except ValueError:
        return "grasp"
    return MODES.get(action, "grasp")


def lowest_safe_tcp_height(robot: RobotModel, padding_m: float) -> float:
    """The TCP height (pointing down) at which the fingers, grown by the gate's padding, just clear the table: lower
    contacts would only be refused by the gate later."""
    T_down = np.diag([1.0, -1.0, -1.0, 1.0])  # TCP at the table top, approach axis pointing down
    lowest = GripperBoxes(robot, padding_m).lowest_z(T_down, robot.spec.gripper.min_width_m)
    return -lowest + TABLE_MARGIN_M


def instruction_action(instruction: str) -> str | None:
    """The grammar's action of the sentence, None for free text (a model backend's)."""
    try:
        return parse_instruction(instruction).action
    except ValueError:
        return None


def contact_config(ctx: RunContext, robot: RobotModel) -> ContactConfig:
    """The profile's contact settings made to propose only what the gate passes (see the module docstring); a
    lift is held at its goal, with no set-down poses above it."""
    padding = ctx.profile.safety.padding_m
    config = ctx.profile.pipeline.contact
    lifts = () if instruction_action(ctx.instruction) == "lift" else place_heights(padding)
    return config.model_copy(
        update={
            "min_tcp_height_m": max(config.min_tcp_height_m, lowest_safe_tcp_height(robot, padding)),
            "collision_padding_m": max(config.collision_padding_m, padding),
            "place_lifts_m": lifts,
        }
    )


def contact_plans(ctx: RunContext, clouds: SceneClouds, robot: RobotModel, q_start: np.ndarray) -> list[ContactPlan]:
    """Ranked contact plans, recorded; StageError with pipeline.contact's rejection counts when there is none.

    A push that cannot be made (mostly for want of room for the hand behind the object: a neighbour within the
    closed fingers' depth, the standoff and the gate's padding) is carried instead when the profile allows it: the
    goal is where the object ends, and a grasp set down there reaches it without the hand going behind. The push's
    rejections are recorded either way (`carried_because`)."""
    mode = contact_mode(ctx.instruction)
    config = contact_config(ctx, robot)
    result = _plan(ctx, clouds, robot, q_start, mode, config)
    carried_because = None
    if mode == "push" and not result.ok and config.carry_when_no_push:
        carried_because = f"no feasible push: {result.reason}"
        mode, result = "grasp", _plan(ctx, clouds, robot, q_start, "grasp", config)
    ctx.record.summary.contact = ContactRecord(
        mode=mode,
        carried_because=carried_because,
        candidates=result.candidates,
        plans=len(result.plans),
        rejected=result.rejected,
        turn_from_grounded_deg=[round(turn_deg(plan.T_motion, ctx.motion.T_base), 1) for plan in result.plans],
    )
    if not result.ok:
        raise StageError(
            f"{carried_because}; no feasible carry instead: {result.reason}"
            if carried_because
            else f"no feasible {mode}: {result.reason}"
        )
    return [
        replace(plan, source=f"pipeline.contact #{rank} score {plan.score:.2f}")
        for rank, plan in enumerate(result.plans, start=1)
    ]


def _plan(
    ctx: RunContext,
    clouds: SceneClouds,
    robot: RobotModel,
    q_start: np.ndarray,
    mode: ContactMode,
    config: ContactConfig,
) -> ContactResult:
    return plan_contacts(
        clouds.target,
        clouds.scene,
        ctx.motion.T_base,
        robot,
        mode=mode,
        config=config,
        q_seed=q_start,
        # the gate's own scene (the table is the contact's table-height filter: a contact at the lowest safe height
        # sits on the padded table's surface)
        collision_world=CollisionWorld(robot, ctx.profile.safety, points=clouds.scene, table=False),
        viewpoint=ctx.frame0.T_base_camera[:3, 3],
        object_name=ctx.goal.target,
        # a grasp's release and the descent to it, the object in the hand, with the table as the carry's gate sees it
        # (the hand let go of a stood-up bottle sideways, low: link6 came down into the padded table)
        release_world=CollisionWorld(robot, ctx.profile.safety, points=clouds.scene),
        hidden_turns=None
        if ctx.motion.symmetry is None
        else ctx.motion.symmetry.box_turns_in(ctx.motion.T_base_camera),
    )
