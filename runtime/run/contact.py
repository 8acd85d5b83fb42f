"""The contact stage for a run: pipeline.contact's ranked plans as ContactPoses the manipulation chain uses.

What the runtime adds is the hand-over: the target's and the scene's points in the base frame (the Chain's, from
the initial capture and the reasoning stage's mask), the mode the instruction asks for, and a model of the
grasped object for the carry phase (its points' bounding box in the TCP frame at the grasp, mirrored across the
closing axis because the camera sees only the object's front).
"""

from __future__ import annotations

import numpy as np

from motion.manipulation.phases import LIFT_M, PLACE_CLEARANCE_M, Chain, ContactPoses
from runtime.run.context import RunContext, StageError
from runtime.run.stages import require
from safety.collision import CollisionWorld
from safety.geometry import Primitive, transform_points

MODES = {"push": "push", "close": "hinge"}  # instruction action -> contact mode (anything else: grasp)
TABLE_MARGIN_M = 0.002


def contact_mode(instruction: str) -> str:
    """push for the grammar's push sentences, hinge (an arc push about the part's hinge) for close, grasp otherwise
    (free text from a model backend included)."""
    parse = require("contact", "pipeline.reasoning.instruction", "parse_instruction")
    try:
        action = parse(instruction).action
    except ValueError:
        return "grasp"
    return MODES.get(action, "grasp")


def held_box(points_base: np.ndarray, T_base_tcp: np.ndarray, tcp_link: str, name: str) -> Primitive:
    """The grasped object as a box in the TCP frame: the points' extent, mirrored about the TCP across the closing
    axis (y) only. The fingers close on the object's middle along y, whose far side the camera may not see; along
    the pads (x) the seen extent is the object's (its top is seen whole), and mirroring it there would give an
    object grasped off its middle (a long bottle) a phantom end that, once the object is turned, reaches into the
    table or the arm."""
    local = transform_points(np.linalg.inv(T_base_tcp), points_base)
    x0, x1 = float(local[:, 0].min()), float(local[:, 0].max())
    half_y = float(np.max(np.abs(local[:, 1])))
    z0, z1 = float(local[:, 2].min()), float(local[:, 2].max())
    T = np.eye(4)
    T[0, 3], T[2, 3] = (x0 + x1) / 2, (z0 + z1) / 2
    return Primitive(f"held:{name}", tcp_link, "box", (x1 - x0, 2 * half_y, z1 - z0), T)


def lowest_safe_tcp_height(ctx: RunContext, chain: Chain) -> float:
    """The TCP height (pointing down) at which the fingers, grown by the gate's padding, just clear the table: lower
    contacts would only be refused by the gate later."""
    GripperBoxes = require("contact", "pipeline.contact.gripper", "GripperBoxes")
    T_down = np.diag([1.0, -1.0, -1.0, 1.0])  # TCP at the table top, approach axis pointing down
    g = chain.robot.spec.gripper
    lowest = GripperBoxes(chain.robot, ctx.profile.safety.padding_m).lowest_z(T_down, g.min_width_m)
    return -lowest + TABLE_MARGIN_M


def contact_candidates(ctx: RunContext, chain: Chain) -> list[ContactPoses]:
    """Ranked ContactPoses; StageError with pipeline.contact's rejection counts when there is none."""
    plan_contacts = require("contact", "pipeline.contact.planner", "plan_contacts")
    ContactConfig = require("contact", "pipeline.contact.types", "ContactConfig")
    turn_deg = require("contact", "pipeline.contact.symmetry", "turn_deg")
    mode = contact_mode(ctx.instruction)
    points = chain.target_points
    config = getattr(ctx.profile.pipeline, "contact", None) or ContactConfig()
    # propose only contacts the gate can pass: the gripper grown by the gate's padding clears table and scene
    padding = ctx.profile.safety.padding_m
    config = config.model_copy(
        update={
            "min_tcp_height_m": max(config.min_tcp_height_m, lowest_safe_tcp_height(ctx, chain)),
            "collision_padding_m": max(config.collision_padding_m, padding),
            "place_lifts_m": (PLACE_CLEARANCE_M + padding, PLACE_CLEARANCE_M + padding + LIFT_M),  # as plan_grasp
        }
    )
    result = plan_contacts(
        points,
        chain.points,
        ctx.motion.T_base,
        chain.robot,
        mode=mode,
        config=config,
        q_seed=chain.q0,
        # the gate's own scene (the table is the contact's table-height filter: a contact at the lowest safe height
        # sits on the padded table's surface)
        collision_world=CollisionWorld(chain.robot, ctx.profile.safety, points=chain.points, table=False),
        viewpoint=ctx.frame0.T_base_camera[:3, 3],
    )
    ctx.record.note(
        contact={
            "mode": mode,
            "candidates": result.candidates,
            "plans": len(result.plans),
            "rejected": result.rejected,
            # per ranked plan, how far its object motion turns from the grounded one (a body of revolution may be
            # set down turned about its own axis, the same goal to the eye); 0 = as grounded
            "turn_from_grounded_deg": [
                round(turn_deg(plan.T_motion, ctx.motion.T_base), 1) if plan.T_motion is not None else 0.0
                for plan in result.plans
            ],
        }
    )
    if not result.ok:
        raise StageError(f"no feasible {mode}: {result.reason}")
    target = getattr(ctx.goal, "target", "target")
    out = []
    for rank, plan in enumerate(result.plans, start=1):
        held, open_w = None, None
        if mode == "grasp":
            held = held_box(points, plan.T_contact, chain.robot.tcp_frame, target)
            open_w = min(chain.robot.spec.gripper.max_width_m, plan.object_width_m + 0.016)
        out.append(
            ContactPoses(
                plan.mode,
                plan.T_pre,
                plan.T_contact,
                plan.T_goal,
                plan.width_m,
                held,
                open_w,
                f"pipeline.contact #{rank} score {plan.score:.2f}",
                plan.via,
                ctx.motion.T_base if plan.T_motion is None else plan.T_motion,
            )
        )
    return out
