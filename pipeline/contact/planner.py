"""Contact planning: candidates on the object cloud, filtered, checked for reachability, scored, ranked.

Modes: grasp, push (straight, horizontal) and hinge (an arc push turning a hinged part, hinge.py).
Filters, in order of cost: orientation cone; gripper boxes against the scene (target excluded) and the table;
along an arc and at the goal, the gripper, and the placed object, against the scene; IK (the safety model's) of
the pre-contact, contact, arc and goal poses, optionally collision-free in a safety CollisionWorld. Every
rejection is counted under a readable reason so a refusal says what ruled the candidates out.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
from scipy.spatial import cKDTree

from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.hinge import HingeError, arc_candidates, hinge_from_motion
from pipeline.contact.sampling import Candidate, estimate_normals, grasp_candidates, push_candidates
from pipeline.contact.types import ContactConfig, ContactMode, ContactPlan, ContactResult
from safety.geometry import transform_points
from safety.ik import IKSettings
from safety.robot_model import RobotModel

IK_SETTINGS = IKSettings(restarts=6, max_iterations=80)


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
) -> ContactResult:
    """Ranked contact plans for moving the object by T_base_motion (x_goal = T x_init, base frame).

    object_points: the target's cloud (N, 3), base frame; scene_points: everything else seen (table points may
    be included: anything below 5 mm is ignored). collision_world: a safety.collision.CollisionWorld without the
    target, used to accept only collision-free IK solutions. viewpoint: camera position (for normals).
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
        candidates, why = grasp_candidates(pts, normals, cfg, robot.spec.gripper.max_width_m)
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
    moved = transform_points(T_base_motion, pts)
    scene_tree = cKDTree(scene) if len(scene) else None
    geometric = []
    for c in candidates:
        reason = _geometric_reason(c, cfg, gripper, scene, moved, scene_tree, T_base_motion, robot)
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
    for c in geometric[: cfg.ik_candidates]:
        plan = _reachable_plan(c, cfg, robot, seed, T_base_motion, collision_world)
        if isinstance(plan, str):
            rejected[plan] += 1
        else:
            plans.append(plan)
        if len(plans) == cfg.keep:
            break
    rejected["not checked for reachability (enough plans)"] += max(0, len(geometric) - cfg.ik_candidates)
    plans.sort(key=lambda p: -p.score)
    return ContactResult(plans, {k: v for k, v in rejected.items() if v}, total)


def _geometric_reason(
    c: Candidate,
    cfg: ContactConfig,
    gripper: GripperBoxes,
    scene: np.ndarray,
    moved: np.ndarray,
    scene_tree,
    T_motion: np.ndarray,
    robot: RobotModel,
) -> str:
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
    T_goal = _goal(c, T_motion)
    held_width = c.object_width_m if c.mode == "grasp" else 0.0
    if gripper.lowest_z(T_goal, held_width) < 0.0:
        return "gripper below the table at the goal"
    if gripper.hits_points(T_goal, held_width, scene):
        return "gripper hits the scene at the goal"
    if c.mode == "grasp" and scene_tree is not None:
        d, _ = scene_tree.query(moved, distance_upper_bound=cfg.placed_clearance_m)
        if np.isfinite(d).mean() > 0.02:
            return "placed object overlaps the scene"
    return ""


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


def _reachable_plan(
    c: Candidate, cfg: ContactConfig, robot: RobotModel, seed: np.ndarray, T_motion: np.ndarray, world
) -> ContactPlan | str:
    T_pre = _pre_contact(c, cfg.pre_distance_m)
    T_goal = _goal(c, T_motion)
    accept = None if world is None else (lambda q: not world.in_collision(q))
    qs = []
    arc = [(T, "arc") for T in c.via]
    for T, where in ((T_pre, "pre-contact"), (c.T_contact, "contact"), *arc, (T_goal, "goal")):
        r = robot.ik(T, qs[-1] if qs else seed, settings=IK_SETTINGS, accept=accept)
        if not r.success:
            return f"{where} pose out of reach"
        qs.append(r.q)
    margin = min(float(np.min(np.minimum(q - robot.lower, robot.upper - q))) for q in qs)
    reach = float(np.clip(margin / 0.5, 0.0, 1.0))
    scores = {"antipodal": c.antipodal, "centred": c.centred, "approach": c.approach, "reach": reach}
    w = cfg.weights
    total = sum(w[k] * v for k, v in scores.items()) / sum(w.values())
    width = robot.spec.gripper.min_width_m if c.mode != "grasp" else max(0.0, c.object_width_m - cfg.squeeze_m)
    q_pre, q_contact, *q_via, q_goal = qs
    return ContactPlan(
        c.mode,
        T_pre,
        c.T_contact,
        T_goal,
        width,
        c.object_width_m,
        total,
        scores,
        q_pre,
        q_contact,
        q_goal,
        c.via,
        tuple(q_via),
    )
