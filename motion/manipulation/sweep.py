"""A sweep with a hand tool, phase by phase, each approved by the gate against its own collision world.

  approach     free path to above the tool's handle (tool, group and scene are obstacles), open
  grasp tool   straight down, close, straight up (the tool is what is touched)
  carry tool   free path, the tool held (grown by the robot's padding), to above the first stroke's start
  sweep        per stroke, at STROKE_SPEED_M_S: straight down behind the group, straight along into the
               container, straight up, then straight over to above the next stroke's start; the tool held with
               its own small margin (its bristles skim the table) and the group not an obstacle (the tool pushes
               it); the container's walls and everything else are
  carry back   free path, the tool held (robot's padding), to above where it lay; the group where it goes is an
               obstacle (where it was, the strokes cleared)
  put down     straight down until the tool is just above where it lay (its own margin), open
  retreat      straight up
  home         free path home; the tool and the group where it goes are obstacles
The free paths end at the joints sweep planning solved, checked in each phase's world.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from motion.goals import lifted
from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.phases import CLOSE_S, LIFT_M, OPEN_S, ManipulationPlan
from motion.timing import GripperAction
from safety.collision import CollisionWorld
from safety.geometry import Primitive, transform_points

STROKE_SPEED_M_S = 0.15  # the tool's speed while it pushes: small parts thrown faster roll and bounce away


class Stroke(Protocol):
    T_above_start: np.ndarray
    T_start: np.ndarray
    T_end: np.ndarray
    T_above_end: np.ndarray
    q_above_start: np.ndarray


class SweepContact(Protocol):
    """What the phases read of a sweep decision (pipeline.contact.sweep.SweepPlan)."""

    mode: str
    T_pre: np.ndarray
    T_contact: np.ndarray
    q_pre: np.ndarray
    q_contact: np.ndarray
    width_m: float
    open_width_m: float
    held: Primitive
    strokes: tuple[Stroke, ...]
    T_place: tuple[np.ndarray, np.ndarray]
    q_place: tuple[np.ndarray, np.ndarray]
    T_motion: np.ndarray
    tool_padding_m: float
    source: str


def plan_sweep_phases(chain: ManipulationChain, contact: SweepContact, tool_points: np.ndarray) -> ManipulationPlan:
    """The gate-approved phases of a sweep. chain: its scene is everything but the group and the tool, its target
    the group; tool_points: the tool as it lies (an obstacle until grasped and once put back)."""
    if not contact.strokes:
        raise ManipulationRefused("sweep: the plan has no stroke")
    g = chain.robot.spec.gripper
    tool = np.asarray(tool_points, dtype=np.float64).reshape(-1, 3)
    group = chain.target_points
    moved = transform_points(contact.T_motion, group)
    everything_before = np.vstack([chain.scene_points, group, tool])
    after = np.vstack([chain.scene_points, moved])

    def world(points: np.ndarray, width: float, held: Primitive | None = None, own_margin: bool = False):
        padding = contact.tool_padding_m if own_margin else None
        return CollisionWorld(
            chain.robot, chain.safety, points=points, held=held, gripper_width_m=width, held_padding_m=padding
        )

    before = world(everything_before, g.max_width_m)
    before_planner = chain.planner(before)
    touching = world(np.vstack([chain.scene_points, group]), contact.open_width_m)
    planner = chain.planner(touching)
    down = chain.descent(before_planner, planner, contact, "down to the tool's handle", "pre-grasp pose of the tool")
    to_pre = chain.free(before_planner, chain.q0, down[0], "path to the tool")
    approach = chain.approved(
        [to_pre, GripperAction("open", OPEN_S, contact.open_width_m)], before, chain.q0, "approach", free_move=True
    )
    up = chain.line(planner, down[-1], lifted(contact.T_contact, LIFT_M), "lift the tool")
    closing = GripperAction("close", CLOSE_S, contact.width_m)
    grasp = chain.approved([down, closing, up], touching, down[0], "grasp tool")

    carrying = world(np.vstack([chain.scene_points, group]), contact.width_m, contact.held)
    planner = chain.planner(carrying)
    first = contact.strokes[0]
    q_first = chain.checked(planner, first.q_above_start, first.T_above_start, "above the first stroke")
    to_first = chain.free(planner, up[-1], q_first, "carry the tool to the first stroke")
    carry = chain.approved([to_first], carrying, up[-1], "carry tool", free_move=True)

    sweeping = world(chain.scene_points, contact.width_m, contact.held, own_margin=True)
    planner = chain.planner(sweeping)
    path, q = [], q_first
    for k, stroke in enumerate(contact.strokes, start=1):
        if k > 1:
            path.append(chain.line(planner, q, stroke.T_above_start, f"over to stroke {k}"))
            q = path[-1][-1]
        for T, what in ((stroke.T_start, "down behind the group"), (stroke.T_end, "along"), (stroke.T_above_end, "up")):
            path.append(chain.line(planner, q, T, f"stroke {k}: {what}"))
            q = path[-1][-1]
    strokes = chain.approved(path, sweeping, q_first, "sweep", tcp_speed_m_s=STROKE_SPEED_M_S)

    (T_release, T_above), (_, q_above) = contact.T_place, contact.q_place
    back_world = world(after, contact.width_m, contact.held)
    planner = chain.planner(back_world)
    q_above = chain.checked(planner, q_above, T_above, "above where the tool lay")
    back = chain.approved(
        [chain.free(planner, q, q_above, "carry the tool back")], back_world, q, "carry back", free_move=True
    )

    setting = world(after, contact.width_m, contact.held, own_margin=True)
    lower = chain.line(chain.planner(setting), q_above, T_release, "put the tool down")
    put_down = chain.approved([lower, GripperAction("open", OPEN_S, g.max_width_m)], setting, q_above, "put down")

    released = world(after, g.max_width_m)
    rise = chain.line(chain.planner(released), lower[-1], T_above, "retreat from the tool")
    retreat = chain.approved([rise], released, lower[-1], "retreat")

    homing = world(np.vstack([after, tool]), g.max_width_m)
    to_home = chain.free(chain.planner(homing), rise[-1], chain.rest(homing), "path home")
    home = chain.approved([to_home], homing, rise[-1], "home", free_move=True)

    phases = (approach, grasp, carry, strokes, back, put_down, retreat, home)
    names = ("approach", "grasp tool", "carry tool", "sweep", "carry back", "put down", "retreat", "home")
    waypoints = {"tool grasp": contact.T_contact}
    for k, stroke in enumerate(contact.strokes, start=1):
        waypoints |= {f"stroke {k} start": stroke.T_start, f"stroke {k} end": stroke.T_end}
    waypoints["tool put back"] = T_release
    return ManipulationPlan(phases, names, contact, waypoints)
