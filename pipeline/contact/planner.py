"""Contact planning: candidates on the object cloud, filtered, checked for reachability, scored, ranked.

Modes: grasp, push (straight, horizontal) and hinge (an arc push turning a hinged part, hinge.py).
Filters, in order of cost: orientation cone; gripper boxes against the scene (target excluded) and the table;
along an arc and at the goal, the gripper, and the placed object, against the scene; IK (the safety model's) of
the pre-contact, contact, arc and goal poses (a grasp's goal with the poses config.place_lifts_m above it that
the object is set down from), optionally collision-free in a safety CollisionWorld. Every rejection is counted
under a readable reason so a refusal says what ruled the candidates out.

Two freedoms the candidates do not spell out are used when a candidate's IK fails. The parallel gripper looks the
same after a half turn about its approach axis, but the wrist does not (link7 is off its axis): one twin may
fold link5 onto link7 where the other is free. And a grasped body of revolution (symmetry.py) reaches the same
goal turned about its own axis, a turn the images cannot show, so the goal is also tried turned about that axis;
the plan then carries the object motion it realises (ContactPlan.T_motion).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.held import held_box
from pipeline.contact.hinge import HingeError, arc_candidates, hinge_from_motion
from pipeline.contact.sampling import (
    Candidate,
    estimate_normals,
    grasp_candidates,
    push_candidates,
    support_height,
)
from pipeline.contact.symmetry import revolution_axis, turn_deg
from pipeline.contact.types import ContactConfig, ContactMode, ContactPlan, ContactResult
from safety.geometry import transform_points
from safety.ik import IKSettings
from safety.robot_model import RobotModel

IK_SETTINGS = IKSettings(restarts=6, max_iterations=80)
HALF_TURN = np.diag([-1.0, -1.0, 1.0, 1.0])  # about the TCP's approach axis: the same grasp, the other wrist
SPIN_DEG = (45.0, -45.0, 90.0, -90.0, 135.0, -135.0, 180.0)  # turns of a body of revolution about its axis


def plan_contacts(
    object_points: np.ndarray,
    scene_points: np.ndarray,
    T_base_motion: np.ndarray,
    robot: RobotModel,
    *,
    mode: ContactMode = "grasp",
    config: ContactConfig | None = None,
    q_seed: np.ndarray | None = None,
    collision_world=None,
    viewpoint: np.ndarray | None = None,
    object_name: str = "object",
) -> ContactResult:
    """Ranked contact plans for moving the object by T_base_motion (x_goal = T x_init, base frame).

    object_points: the target's cloud (N, 3), base frame; scene_points: everything else seen (table points may
    be included: anything below 5 mm is ignored). collision_world: a safety.collision.CollisionWorld without the
    target: IK solutions of the pre-contact, contact and arc poses must be collision-free in it with the fingers at
    the candidate's opening (the exact geometry the gate will judge the approach in), those of the goal pose free of
    self-collision, workspace and keep-out (at the goal the object is set down from above with a clearance, so
    the scene there is the geometric filter's). viewpoint: camera position (for normals). object_name: names a
    grasped object's held box (ContactPlan.held) in the gate's reports.
    """
    cfg = config or ContactConfig()
    pts = np.asarray(object_points, dtype=np.float64).reshape(-1, 3)
    if len(pts) < 20:
        return ContactResult([], {"object cloud has fewer than 20 points": 1}, 0)
    scene = np.asarray(scene_points, dtype=np.float64).reshape(-1, 3)
    scene = scene[scene[:, 2] > 0.005]
    eye = np.array([1.0, 0.0, 1.0]) if viewpoint is None else np.asarray(viewpoint, dtype=np.float64)
    normals = estimate_normals(pts, 0.01, eye)
    rejected: Counter[str] = Counter()
    gripper = GripperBoxes(robot, cfg.collision_padding_m)
    if mode == "grasp":
        candidates, why = grasp_candidates(
            pts, normals, cfg, robot.spec.gripper.max_width_m, support_height(pts, scene)
        )
        rejected.update(why)
    elif mode == "hinge":
        try:
            hinge = hinge_from_motion(T_base_motion, cfg.hinge_max_slide_m, cfg.hinge_min_turn_deg)
        except HingeError as e:
            candidates, why = [], {str(e): 1}
        else:
            g = robot.spec.gripper
            fingers = GripperBoxes(robot, 0.0).corners_tcp(g.min_width_m, g.finger_links)
            candidates, why = arc_candidates(pts, hinge, cfg, fingers)
        rejected.update(why)
    else:
        shift = transform_points(T_base_motion, pts.mean(axis=0)[None])[0] - pts.mean(axis=0)
        candidates = push_candidates(pts, shift, cfg)
        if not candidates:
            rejected["no horizontal motion to push along"] += 1
    total = len(candidates) + sum(rejected.values())
    motions = _motions(pts, T_base_motion, mode)
    scene_tree = cKDTree(scene) if len(scene) else None
    goal_check = _GoalCheck(cfg, gripper, scene, scene_tree, [transform_points(M, pts) for M in motions])
    geometric = []
    for c in candidates:
        reason = _contact_reason(c, cfg, gripper, scene, robot) or goal_check.first_reason(c, motions)
        if reason:
            rejected[reason] += 1
        else:
            geometric.append(c)
    w = cfg.weights
    geometric.sort(
        key=lambda c: -(w["antipodal"] * c.antipodal + w["centred"] * c.centred + w["approach"] * c.approach)
    )
    plans = []
    seed = robot.home_q if q_seed is None else np.asarray(q_seed, dtype=np.float64)
    placing = _Placing(pts, object_name, robot.tcp_frame)
    for c in geometric[: cfg.ik_candidates]:
        try:
            plans.append(_reachable_plan(c, cfg, robot, seed, motions, goal_check, collision_world, placing))
        except _Unreachable as e:
            rejected[e.reason] += 1
        if len(plans) == cfg.keep:
            break
    rejected["not checked for reachability (enough plans)"] += max(0, len(geometric) - cfg.ik_candidates)
    # the grounded motion first, then the least turn about a body's axis: the turn is not in the images, but the
    # verification's registration may still see part of it
    plans.sort(key=lambda p: (round(turn_deg(p.T_motion, T_base_motion)), -p.score))
    return ContactResult(plans, {k: v for k, v in rejected.items() if v}, total)


def _motions(points: np.ndarray, T_motion: np.ndarray, mode: ContactMode) -> list[np.ndarray]:
    """The object motion, then (a grasped body of revolution) the same goal turned about the body's own axis."""
    axis = revolution_axis(points) if mode == "grasp" else None
    if axis is None:
        return [T_motion]
    return [T_motion, *(T_motion @ axis.turn(np.radians(a)) for a in SPIN_DEG)]


def _contact_reason(
    c: Candidate, cfg: ContactConfig, gripper: GripperBoxes, scene: np.ndarray, robot: RobotModel
) -> str:
    """Why the candidate cannot be approached and touched (empty when it can)."""
    tilt = np.degrees(np.arccos(np.clip(-c.T_contact[2, 2], -1, 1)))
    if tilt > cfg.max_tilt_deg:
        return f"approach outside the {cfg.max_tilt_deg:.0f} deg cone"
    width = _open_width(c, cfg, robot)
    T_pre = _pre_contact(c, cfg.pre_distance_m)
    for T, where in ((c.T_contact, "contact"), (T_pre, "pre-contact")):
        if gripper.lowest_z(T, width) < 0.0:
            return f"gripper below the table at {where}"
        if gripper.hits_points(T, width, scene):
            return f"gripper hits the scene at {where}"
    for T in c.via:
        if gripper.lowest_z(T, width) < 0.0:
            return "gripper below the table along the arc"
        if gripper.hits_points(T, width, scene):
            return "gripper hits the scene along the arc"
    return ""


class _GoalCheck:
    """The gripper at the goal against table and scene, and the moved object against the scene, per motion."""

    def __init__(self, cfg: ContactConfig, gripper: GripperBoxes, scene, scene_tree, moved: list[np.ndarray]) -> None:
        self.cfg, self.gripper, self.scene, self.tree = cfg, gripper, scene, scene_tree
        self.placed_reason = [self._placed_reason(m) for m in moved]

    def _placed_reason(self, moved: np.ndarray) -> str:
        if self.tree is None:
            return ""
        d, _ = self.tree.query(moved, distance_upper_bound=self.cfg.placed_clearance_m)
        return "placed object overlaps the scene" if np.isfinite(d).mean() > 0.02 else ""

    def reason(self, c: Candidate, T_goal: np.ndarray, k: int) -> str:
        """Why the candidate cannot end at T_goal under the k-th motion (empty when it can)."""
        held_width = c.object_width_m if c.mode == "grasp" else 0.0
        if self.gripper.lowest_z(T_goal, held_width) < 0.0:
            return "gripper below the table at the goal"
        if self.gripper.hits_points(T_goal, held_width, self.scene):
            return "gripper hits the scene at the goal"
        return self.placed_reason[k] if c.mode == "grasp" else ""

    def first_reason(self, c: Candidate, motions: list[np.ndarray]) -> str:
        """The first motion's reason when the candidate can end under none of them (empty when it can)."""
        reasons = [self.reason(c, _goal(c, M), k) for k, M in enumerate(motions)]
        return "" if not all(reasons) else reasons[0]


def _goal(c: Candidate, T_motion: np.ndarray) -> np.ndarray:
    return T_motion @ c.T_contact if c.T_goal is None else c.T_goal


def _open_width(c: Candidate, cfg: ContactConfig, robot: RobotModel) -> float:
    if c.mode != "grasp":
        return robot.spec.gripper.min_width_m
    return min(robot.spec.gripper.max_width_m, c.object_width_m + 2 * cfg.finger_clearance_m)


def _pre_contact(c: Candidate, distance_m: float) -> np.ndarray:
    """The contact pose backed off by distance_m: up its approach axis, or along the candidate's own direction."""
    out = c.T_contact.copy()
    out[:3, 3] += distance_m * (-c.T_contact[:3, 2] if c.back_off is None else c.back_off)
    return out


def _half_turn(c: Candidate) -> Candidate:
    """The same contact with the gripper turned half a turn about its approach axis."""
    return replace(
        c,
        T_contact=c.T_contact @ HALF_TURN,
        via=tuple(T @ HALF_TURN for T in c.via),
        T_goal=None if c.T_goal is None else c.T_goal @ HALF_TURN,
    )


class _Unreachable(Exception):
    """A candidate with no reachable plan; reason is the rejection it is counted under."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class _Placing:
    """What a grasp plan's held box is made of: the object's points, its name and the TCP link."""

    points: np.ndarray
    name: str
    tcp_link: str


def _reachable_plan(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    seed: np.ndarray,
    motions: list[np.ndarray],
    goal_check: _GoalCheck,
    world,
    placing: _Placing,
) -> ContactPlan:
    """The candidate's plan, from the first wrist twin and object motion whose poses all have IK; else _Unreachable
    with why the candidate as sampled (first twin, first motion) fails."""
    accept, accept_goal = None, None
    if world is not None:
        width = _open_width(c, cfg, robot)
        accept = lambda q: not world.in_collision(q, width)  # noqa: E731
        accept_goal = lambda q: all(k.kind == "collision" for k in world.check(q, width))  # noqa: E731
    first: _Unreachable | None = None
    for twin in (c, _half_turn(c)):
        try:
            return _twin_plan(twin, cfg, robot, seed, motions, goal_check, accept, accept_goal, placing)
        except _Unreachable as e:
            first = first or e
    raise first


def _twin_plan(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    seed: np.ndarray,
    motions: list[np.ndarray],
    goal_check: _GoalCheck,
    accept,
    accept_goal,
    placing: _Placing,
) -> ContactPlan:
    """The plan of this twin under the first motion whose goal passes the goal checks and has IK; else
    _Unreachable."""
    T_pre = _pre_contact(c, cfg.pre_distance_m)
    qs = []
    arc = [(T, "arc") for T in c.via]
    for T, where in ((T_pre, "pre-contact"), (c.T_contact, "contact"), *arc):
        r = robot.ik(T, qs[-1] if qs else seed, settings=IK_SETTINGS, accept=accept)
        if not r.success:
            raise _Unreachable(f"{where} pose out of reach")
        qs.append(r.q)
    lifts = cfg.place_lifts_m if c.mode == "grasp" else ()
    for k, M in enumerate(motions):
        T_goal = _goal(c, M)
        if goal_check.reason(c, T_goal, k):
            continue
        goal = _goal_ik(robot, T_goal, lifts, qs[-1], accept_goal)
        if goal is not None:
            return _plan(c, cfg, robot, T_pre, M, qs, goal, placing)
    raise _Unreachable("goal pose out of reach")


def _goal_ik(
    robot: RobotModel, T_goal: np.ndarray, lifts: tuple[float, ...], q_from: np.ndarray, accept
) -> list[tuple[np.ndarray, np.ndarray]] | None:
    """(pose, IK) of the goal pose and of the poses `lifts` above it, each seeded by the last; None if one has
    none."""
    out = []
    for lift in (0.0, *lifts):
        T = T_goal.copy()
        T[2, 3] += lift
        r = robot.ik(T, out[-1][1] if out else q_from, settings=IK_SETTINGS, accept=accept)
        if not r.success:
            return None
        out.append((T, r.q))
    return out


def _plan(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    T_pre: np.ndarray,
    T_motion: np.ndarray,
    qs: list[np.ndarray],
    goal: list[tuple[np.ndarray, np.ndarray]],
    placing: _Placing,
) -> ContactPlan:
    """qs: the pre-contact, contact and arc joints; goal: (pose, joints) at the goal and the place lifts."""
    (T_goal, q_goal), *place = goal
    margin = min(float(np.min(np.minimum(q - robot.lower, robot.upper - q))) for q in [*qs, q_goal])
    reach = float(np.clip(margin / 0.5, 0.0, 1.0))
    scores = {"antipodal": c.antipodal, "centred": c.centred, "approach": c.approach, "reach": reach}
    w = cfg.weights
    total = sum(w[k] * v for k, v in scores.items()) / sum(w.values())
    grasp = c.mode == "grasp"
    width = robot.spec.gripper.min_width_m if not grasp else max(0.0, c.object_width_m - cfg.squeeze_m)
    q_pre, q_contact, *q_via = qs
    return ContactPlan(
        mode=c.mode,
        T_pre=T_pre,
        T_contact=c.T_contact,
        T_goal=T_goal,
        T_motion=T_motion,
        width_m=width,
        open_width_m=_open_width(c, cfg, robot),
        object_width_m=c.object_width_m,
        q_pre=q_pre,
        q_contact=q_contact,
        q_goal=q_goal,
        via=c.via,
        q_via=tuple(q_via),
        T_place=tuple(T for T, _ in place),
        q_place=tuple(q for _, q in place),
        held=held_box(placing.points, c.T_contact, tcp_link=placing.tcp_link, name=placing.name) if grasp else None,
        score=total,
        scores=scores,
    )
