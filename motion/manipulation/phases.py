"""From a contact decision to gate-approved trajectories: the pick-and-place or push sequence, phase by phase.

The safety gate checks a trajectory against one collision world, and the world changes during a manipulation
(the object is an obstacle until the hand reaches it, then rides in the gripper, then stands somewhere new), so
the sequence is cut where it changes and each phase is approved against its own world. The arm rests at every
cut anyway (rest-to-rest timing at waypoints), so the cuts cost no time.
  grasp:  approach (free path to the pre-grasp pose; the object is an obstacle) -> grasp (straight in, close,
          straight up) -> carry (object attached to the TCP: free path above the place pose, straight down to the
          release, open to the contact's release width) -> retreat (back along the approach axis, else straight
          up) -> home (the placed object is an obstacle; home raised where it stands in the way). The release is
          the contact's: just above the goal, or higher where the fingers would touch the scene lower (a
          container's walls), the object dropping the rest, the fingers opened as wide as the scene there lets (at
          least as the approach opened them).
  push:   approach (free path, close the fingers) -> push (straight in, push along the motion at
          motion.push_tcp_speed_m_s, back off along the tilted hand, else straight up) -> home
  hinge:  as push, the push following the via poses along the hinged part's arc (a Cartesian line between each
          two), ending just off the turned part, whence straight up is away from it
  lift:   approach -> grasp (straight in, close, up until the held object clears the padded table) -> lift (the
          object held: straight to the goal pose above), and the arm holds it there (a pick-up: nothing is put
          back unless asked)
  sweep:  a tool grasped, strokes, the tool put back: sweep.py
The free paths end at the joints contact planning solved (pre-contact, above the place), checked in each phase's
world; the lines between them follow the TCP. Where the line down from the pre-contact joints is not free, the line
up from the contact's own joints is taken the other way, and the free path ends where it starts (chain.descent).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from motion.approval import ApprovedTrajectory
from motion.goals import lifted
from motion.manipulation.chain import ManipulationChain, ManipulationRefused
from motion.manipulation.contact import Contact
from motion.planner import Planner
from motion.timing import GripperAction
from safety.collision import CollisionWorld
from safety.geometry import transform_points

LIFT_M = 0.10  # straight up after grasping / after releasing
PLACE_CLEARANCE_M = 0.015  # the object is released this far above its goal resting pose (beyond padding)
CLOSE_S, OPEN_S = 1.0, 0.6  # the arm holds still while the gripper moves


def place_heights(padding_m: float) -> tuple[float, float]:
    """Heights above a grasp's goal pose of the release and of the pose above it (contact planning solves both):
    the release clears the goal by the gate's padding and PLACE_CLEARANCE_M, the retreat rises LIFT_M."""
    release = PLACE_CLEARANCE_M + padding_m
    return release, release + LIFT_M


@dataclass(frozen=True)
class ManipulationPlan:
    phases: tuple[ApprovedTrajectory, ...]
    phase_names: tuple[str, ...]
    contact: Contact
    tcp_waypoints: dict[str, np.ndarray] = field(default_factory=dict)  # named TCP poses, for the operator's view

    @property
    def duration_s(self) -> float:
        return float(sum(p.trajectory.duration_s for p in self.phases))

    @property
    def samples(self) -> int:
        return int(sum(len(p.trajectory.positions) for p in self.phases))

    @property
    def peak_joint_speed_rad_s(self) -> list[float]:
        peaks = [np.abs(p.trajectory.derivative(1)).max(axis=0) for p in self.phases]
        return np.max(peaks, axis=0).tolist()


def _approach(
    chain: ManipulationChain, contact: Contact, planner: Planner, gripper: GripperAction, pre: str, what: str
) -> tuple[ApprovedTrajectory, np.ndarray]:
    """Free path to the pre-contact joints, the object an obstacle until touched, then the gripper action; and the
    line down to the contact (in planner's world), which starts at those joints (ManipulationChain.descent)."""
    before = chain.world(chain.robot.spec.gripper.max_width_m, obstacle=chain.target_points)
    before_planner = chain.planner(before)
    down = chain.descent(before_planner, planner, contact, what, pre)
    to_pre = chain.free(before_planner, chain.q0, down[0], f"path to the {pre}")
    approach = chain.approved([to_pre, gripper], before, chain.q0, "approach", free_move=True)
    return approach, down


def plan_grasp(chain: ManipulationChain, contact: Contact) -> ManipulationPlan:
    if len(contact.T_place) != 2 or len(contact.q_place) != 2:
        raise ManipulationRefused(
            f"grasp: the contact carries {len(contact.T_place)} poses to set the object down from (need the "
            "release and the pose above it, place_heights)"
        )
    (T_place, T_above), (_, q_above) = contact.T_place, contact.q_place
    touching = chain.world(contact.open_width_m)  # the approach ended opening the fingers: no wider down to it
    planner = chain.planner(touching)
    opening = GripperAction("open", OPEN_S, contact.open_width_m)
    approach, down = _approach(chain, contact, planner, opening, "pre-grasp pose", "approach to the grasp")
    lift = chain.line(planner, down[-1], lifted(contact.T_contact, LIFT_M), "lift after the grasp")
    grasp = chain.approved([down, GripperAction("close", CLOSE_S, contact.width_m), lift], touching, down[0], "grasp")

    carry_world = chain.world(contact.width_m, held=contact.held)
    carry_planner = chain.planner(carry_world)
    q_above = chain.checked(carry_planner, q_above, T_above, "pose above the place")
    to_above = chain.free(carry_planner, lift[-1], q_above, "carry path")
    place = chain.line(carry_planner, q_above, T_place, "descent to the place pose")
    # let go as wide as contact planning found clear there: in a container, beside a neighbour, no wider than the
    # approach; in the open wide, so the fingers leave the object without dragging it
    release = GripperAction("open", OPEN_S, contact.release_width_m)
    carry = chain.approved([to_above, place, release], carry_world, lift[-1], "carry")

    released = chain.world(contact.release_width_m)
    after = _after(chain, contact, contact.release_width_m)
    up = _retreat(chain, chain.planner(released), place[-1], T_place, after, "retreat", (T_above,))
    retreat = chain.approved([up], released, place[-1], "retreat")
    home = _home(chain, after, up[-1])
    phases = (approach, grasp, carry, retreat, home)
    waypoints = {"pre-grasp": contact.T_pre, "grasp": contact.T_contact, "place": T_place}
    return ManipulationPlan(phases, ("approach", "grasp", "carry", "retreat", "home"), contact, waypoints)


def plan_lift(chain: ManipulationChain, contact: Contact) -> ManipulationPlan:
    """Grasp the object and lift it to its goal pose, and hold it there. It rises first as a grasp does (it rests
    on the table, which the held object grown by the padding would touch), then held, to the goal."""
    touching = chain.world(contact.open_width_m)
    planner = chain.planner(touching)
    opening = GripperAction("open", OPEN_S, contact.open_width_m)
    approach, down = _approach(chain, contact, planner, opening, "pre-grasp pose", "approach to the grasp")
    clear = min(place_heights(chain.safety.padding_m)[0], float(contact.T_goal[2, 3] - contact.T_contact[2, 3]))
    rise = chain.line(planner, down[-1], lifted(contact.T_contact, clear), "rise off the table")
    grasp = chain.approved([down, GripperAction("close", CLOSE_S, contact.width_m), rise], touching, down[0], "grasp")
    waypoints = {"pre-grasp": contact.T_pre, "grasp": contact.T_contact, "lifted": contact.T_goal}
    if np.linalg.norm(contact.T_goal[:3, 3] - chain.robot.tcp_pose(rise[-1])[:3, 3]) < 1e-3:
        return ManipulationPlan((approach, grasp), ("approach", "grasp"), contact, waypoints)
    holding = chain.world(contact.width_m, held=contact.held)
    up = chain.line(chain.planner(holding), rise[-1], contact.T_goal, "lift to the goal")
    lift = chain.approved([up], holding, rise[-1], "lift")
    return ManipulationPlan((approach, grasp, lift), ("approach", "grasp", "lift"), contact, waypoints)


def plan_push(chain: ManipulationChain, contact: Contact) -> ManipulationPlan:
    """A straight push, or a hinge push along the via poses of its arc."""
    g = chain.robot.spec.gripper
    touching = chain.world(g.min_width_m)
    planner = chain.planner(touching)
    closing = GripperAction("close", CLOSE_S, g.min_width_m)
    approach, down = _approach(chain, contact, planner, closing, "pre-push pose", "approach to the push")
    path = [down]
    for k, T in enumerate((*contact.via, contact.T_goal), start=1):
        what = f"push (arc pose {k} of {len(contact.via) + 1})" if contact.via else "push"
        path.append(chain.line(planner, path[-1][-1], T, what))
    after = _after(chain, contact, g.min_width_m)
    up = (lifted(contact.T_goal, LIFT_M),)
    # a hinge push ends just off the part it shut: straight up; a straight push ends with the fingertips at the
    # object: back off along the tilted hand first
    back = _retreat(chain, planner, path[-1][-1], contact.T_goal, after, "retreat after the push", up, not contact.via)
    # a straight push moves a free object, which a fast one throws on past the fingers; a hinged part cannot go on
    speed = None if contact.via else chain.motion.push_tcp_speed_m_s
    pushing = chain.approved([*path, back], touching, down[0], "push", tcp_speed_m_s=speed)
    home = _home(chain, after, back[-1])
    arc = {f"arc {k}": T for k, T in enumerate(contact.via, start=1)}
    waypoints = {"pre-push": contact.T_pre, "contact": contact.T_contact, **arc, "push end": contact.T_goal}
    return ManipulationPlan((approach, pushing, home), ("approach", "push", "home"), contact, waypoints)


def _after(chain: ManipulationChain, contact: Contact, width_m: float) -> CollisionWorld:
    """The world once the object was let go: the object where it now is, an obstacle."""
    return chain.world(width_m, obstacle=transform_points(contact.T_motion, chain.target_points))


def _retreat(
    chain: ManipulationChain,
    planner: Planner,
    q_from: np.ndarray,
    T_from: np.ndarray,
    after: CollisionWorld,
    what: str,
    poses: tuple[np.ndarray, ...],
    back_first: bool = True,
) -> np.ndarray:
    """Away from what the hand just let go: back along its approach axis by LIFT_M (a side grasp's fingers leave
    a stood-up bottle sideways, a tilted push's tips leave the object's face), then the given poses (above the
    place), the first line that is free and ends clear of the object where it now is (the way home starts
    there)."""
    backed = T_from.copy()
    backed[:3, 3] -= LIFT_M * T_from[:3, 2]
    tries = [backed, *poses] if back_first else list(poses)
    tries = [T for k, T in enumerate(tries) if all(np.linalg.norm(T[:3, 3] - P[:3, 3]) > 1e-3 for P in tries[:k])]
    home_planner = chain.planner(after)
    first: ManipulationRefused | None = None
    for T in tries:
        try:
            path = chain.line(planner, q_from, T, what)
        except ManipulationRefused as e:
            first = first or e
            continue
        if home_planner.valid(path[-1]):
            return path
        first = first or ManipulationRefused(home_planner.why_invalid(path[-1], f"{what}: the end of the"))
    raise first


def _home(chain: ManipulationChain, world: CollisionWorld, q_start: np.ndarray) -> ApprovedTrajectory:
    """Back to the home posture (raised where the object stands in its way: chain.rest), with the object where it
    now is as an obstacle."""
    path = chain.free(chain.planner(world), q_start, chain.rest(world), "path home")
    return chain.approved([path], world, q_start, "home", free_move=True)


def plan_manipulation(chain: ManipulationChain, contact: Contact) -> ManipulationPlan:
    if contact.mode == "grasp":
        return plan_grasp(chain, contact)
    if contact.mode in ("push", "hinge"):
        return plan_push(chain, contact)
    raise ManipulationRefused(f"unknown contact mode {contact.mode!r}")
