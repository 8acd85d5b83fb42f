"""Contact planning: candidates on the object cloud, filtered, checked for reachability, scored, ranked.

Modes: grasp, push (straight, horizontal) and hinge (an arc push turning a hinged part, hinge.py).
Filters, in order of cost: orientation cone; gripper boxes against the scene (target excluded) and the table;
along an arc and at the goal (a push's end; a grasp's release), the gripper, and the placed object, against the
scene; IK (the safety model's) of the pre-contact, contact, arc and goal poses (a grasp's goal with the poses
above it the object is set down from), optionally collision-free in a safety CollisionWorld. Every rejection is
counted under a readable reason so a refusal says what ruled the candidates out.

A grasp lets go of the object config.place_lifts_m[0] above its goal, or higher (up to config.max_drop_m more)
where the gripper would touch the scene there: into a container whose walls are taller than the fingers are
long, onto an object that stands close, the fingers stay above the rim and the object drops the rest; and higher
(within the same drop) only where no candidate's arm takes its lowest. The gripper is checked there holding the
object and opened as far as it opens to let go, and the joints there and above must be free of the scene with the
object in the hand (the carry's own world), the release's those the straight descent from above arrives with. A
flat object laid on its face by a gripper holding it sideways (a plate grasped at its rim) is let go standing on
its far edge instead, and tips over onto its goal (tipping.py): the release heights are then above that pose.

Two freedoms the candidates do not spell out are used. The parallel gripper looks the same after a half turn about
its approach axis, but the wrist does not (link7 is off its axis): one twin may fold link5 onto link7 where the
other is free, so each twin that is reachable is a plan of its own, the one nearer the hand's present turn first.
And a grasped body of revolution (symmetry.py) reaches the same
goal turned about its own axis, a turn the images cannot show, so the goal is also tried turned about that axis:
first by the turn that keeps the gripper most upright at the goal (the registration's turn about the axis is
arbitrary, and a lying bottle's may roll the grasp into the table), then in 45 deg steps; the plan then carries
the object motion it realises (ContactPlan.T_motion). A box whose turns onto itself no image shows (the symmetry
grounding reported with the motion: a uniform box's half turns, a cube's 24) is carried by the goal's twin that
turns it least: the grounded turn among those is the registration's pick, not the goal's.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
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
from pipeline.contact.symmetry import ball_centre, completed_points, revolution_axis, turn_deg
from pipeline.contact.tipping import flat_normal, tip_turn
from pipeline.contact.types import ContactConfig, ContactMode, ContactPlan, ContactResult
from safety.collision import CollisionWorld
from safety.geometry import Primitive, transform_points, turn_about
from safety.ik import IKSettings
from safety.robot_model import RobotModel

IK_SETTINGS = IKSettings(restarts=6, max_iterations=80)
# the goal and set-down poses, seeded from the contact's joints: most are reached from the seed or not at all, and
# a body of revolution tries them under several turns, so a failing one must fail fast
GOAL_IK_SETTINGS = IKSettings(restarts=2, max_iterations=60)
MAX_TURNS_TRIED = 8  # a body of revolution's goal turns tried per contact, the most natural for the wrist first
HALF_TURN = np.diag([-1.0, -1.0, 1.0, 1.0])  # about the TCP's approach axis: the same grasp, the other wrist
SPIN_DEG = (45.0, -45.0, 90.0, -90.0, 135.0, -135.0, 180.0)  # turns of a body of revolution about its axis
UPRIGHT_STEP_DEG = 5.0  # the search for the turn about a body's axis that keeps a top grasp upright
DROP_STEP_M = 0.01  # release heights tried above the lowest
CELL_MARGIN_M = 0.009  # the gate sees the scene's points as 1 cm cells: a release this much clearer passes it
GROUNDED_TURN_DEG = 1.0  # a plan's motion this close to the grounded one realises it (no turn about an axis)
RELEASE_WIDTH_STEP_M = 0.005  # release openings tried from the gripper's widest down to the approach's
# the manipulation's straight descent to the release, followed as motion.cartesian follows it: steps this long, each
# solved from the last alone, no joint moving more than this in one
LINE_STEP_M, LINE_JUMP_RAD = 0.005, 0.15
LINE_IK_SETTINGS = IKSettings(restarts=0)
PASSES = ((True, False), (False, False), (False, True))  # (IK accepted at the goal pose, releases above the lowest)


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
    release_world=None,
    hidden_turns: np.ndarray | None = None,
) -> ContactResult:
    """Ranked contact plans for moving the object by T_base_motion (x_goal = T x_init, base frame).

    object_points: the target's cloud (N, 3), base frame; scene_points: everything else seen (table points may
    be included: anything below 5 mm is ignored). collision_world: a safety.collision.CollisionWorld without the
    target: IK solutions of the pre-contact, contact and arc poses must be collision-free in it with the fingers at
    the candidate's opening (the exact geometry the gate will judge the approach in), those of the goal pose free of
    self-collision, workspace and keep-out (at the goal the object is set down from above with a clearance, so
    the scene there is the geometric filter's). viewpoint: camera position (for normals). object_name: names a
    grasped object's held box (ContactPlan.held) in the gate's reports. release_world: the world a grasp's release
    is checked in with the object in the hand (default collision_world; a tool's put-back leaves out the tool's
    other parts, which collision_world keeps as obstacles for the approach). hidden_turns: (K, 4, 4) base-frame
    turns of the object onto itself that neither its shape nor its print shows (a box's, reported by grounding).
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
        # a body of revolution is pinched where it is, not where its seen half is: the width and the middle between
        # the pads from its surface completed about its axis (a lying bottle's half facing the robot is unseen)
        body = revolution_axis(pts) if ball_centre(pts) is None else None
        surface = (pts, normals) if body is None else body.completed(pts, normals)
        candidates, why = grasp_candidates(
            *surface,
            cfg,
            robot.spec.gripper.max_width_m,
            support_height(pts, scene),
            None if body is None else pts,
            gripper.corners_tcp(robot.spec.gripper.max_width_m),
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
            clear = _gate_clear(robot, cfg, scene, collision_world, g.min_width_m)
            candidates, why = arc_candidates(pts, hinge, cfg, fingers, clear)
        rejected.update(why)
    else:
        shift = transform_points(T_base_motion, pts.mean(axis=0)[None])[0] - pts.mean(axis=0)
        g = robot.spec.gripper
        fingers = GripperBoxes(robot, 0.0).corners_tcp(g.min_width_m, g.finger_links)
        candidates = push_candidates(completed_points(pts), shift, cfg, gripper.corners_tcp(g.min_width_m), fingers)
        if not candidates:
            rejected["no horizontal motion to push along"] += 1
    total = len(candidates) + sum(rejected.values())
    motions = _motions(pts, T_base_motion, mode, hidden_turns)
    scene_tree = cKDTree(scene) if len(scene) else None
    placing = _Placing(pts, object_name, robot.tcp_frame, release_world)
    goal_check = _GoalCheck(cfg, robot, scene, scene_tree, [transform_points(M, pts) for M in motions], placing)
    geometric, drops = [], {}
    for c in candidates:
        reason = _contact_reason(c, cfg, gripper, scene, robot)
        if not reason:
            drops[id(c)], reason = goal_check.least_drop(c, motions)
        if reason:
            rejected[reason] += 1
        else:
            geometric.append(c)
    w = cfg.weights
    # the object let go lowest first (a narrow can dropped beside a neighbour tips over), then the best scored
    geometric.sort(
        key=lambda c: (
            round(drops[id(c)] * 100),
            -(w["antipodal"] * c.antipodal + w["centred"] * c.centred + w["approach"] * c.approach),
        )
    )
    seed = robot.home_q if q_seed is None else np.asarray(q_seed, dtype=np.float64)
    # a grasp let go above its goal never takes the goal pose itself: only when no candidate has accepted IK there
    # are the poses it does take enough (_goal_ik), so plans that worked before keep their ranks; and only when no
    # candidate can be let go at its lowest release is it let go higher, the object dropping the rest (a can stood
    # up far out to the side: lower, the arm folds into its base)
    for at_goal, higher in PASSES if mode == "grasp" and cfg.place_lifts_m else PASSES[:1]:
        plans, unreachable = [], Counter()
        for c in geometric[: cfg.ik_candidates]:
            try:
                plans += _reachable_plans(
                    c, cfg, robot, seed, motions, goal_check, collision_world, placing, at_goal, higher
                )
            except _Unreachable as e:
                unreachable[e.reason] += 1
            if len(plans) >= cfg.keep:
                plans = plans[: cfg.keep]
                break
        if plans:
            break
    rejected.update(unreachable)
    rejected["not checked for reachability (enough plans)"] += max(0, len(geometric) - cfg.ik_candidates)
    # the object let go lowest first; then the grounded motion (the verification's registration may see part of a
    # turn about a body's axis), then the best grasp, the least turn breaking ties: a contact's turn is the first
    # of those tried (_turns_to_try) its wrist reaches, not a quality; ranked by it, a slanted grasp that turned a
    # stood-up bottle in the fingers came before the square ones
    plans.sort(
        key=lambda p: (
            round(_drop(p, cfg) * 100),
            turn_deg(p.T_motion, T_base_motion) > GROUNDED_TURN_DEG,
            -round(p.score, 3),
            round(turn_deg(p.T_motion, T_base_motion)),
        )
    )
    return ContactResult(plans, {k: v for k, v in rejected.items() if v}, total)


def _gate_clear(
    robot: RobotModel, cfg: ContactConfig, scene: np.ndarray, world: CollisionWorld | None, width_m: float
) -> Callable[[np.ndarray], bool]:
    """Whether the gripper at a TCP pose passes the gate's check against the table and the scene, as the gate sees
    the scene: the octree cells (world.config.cloud_voxel_m, on a grid from the origin) its points fall in. A cell
    lies within half its diagonal of its centre, so the boxes grown by that much more than the padding are checked
    against the cells' centres: never passed where the gate refuses (the raw points with a margin were, by up to
    a cell)."""
    voxel = world.config.cloud_voxel_m if world is not None else 0.0
    cells = scene if not voxel or not len(scene) else (np.unique(np.floor(scene / voxel), axis=0) + 0.5) * voxel
    boxes = GripperBoxes(robot, cfg.collision_padding_m + voxel * math.sqrt(3.0) / 2.0)

    def clear(T: np.ndarray) -> bool:
        return boxes.lowest_z(T, width_m) >= 0.0 and not boxes.hits_points(T, width_m, cells)

    return clear


def _motions(
    points: np.ndarray, T_motion: np.ndarray, mode: ContactMode, hidden_turns: np.ndarray | None = None
) -> list[np.ndarray]:
    """The object motion, then (a grasped body of revolution) the same goal turned about the body's own axis: by
    the turn that keeps the vertical most vertical (a top grasp stays upright), then in SPIN_DEG steps; for a
    grasped ball only its centre's move (the registration's turn of a ball is arbitrary); for a box with
    `hidden_turns` the least-turning of the goal's twins alone; for a flat part the motion and its half turns
    (_flat_turns)."""
    if mode != "grasp":
        return [T_motion]
    centre = ball_centre(points)
    if centre is not None:  # no turn of a ball shows: its goal is where its centre goes, carried without a turn
        T = np.eye(4)
        T[:3, 3] = T_motion[:3, :3] @ centre + T_motion[:3, 3] - centre
        return [T]
    axis = revolution_axis(points)
    if axis is None and hidden_turns is not None:
        return [min((T_motion @ H for H in hidden_turns), key=lambda M: turn_deg(M, np.eye(4)))]
    if axis is None:
        return _flat_turns(points, T_motion)
    turns = np.radians(np.arange(-180.0, 180.0, UPRIGHT_STEP_DEG))
    upright = max(turns, key=lambda a: (T_motion @ axis.turn(a))[2, 2])
    spins = [T_motion @ axis.turn(a) for a in (upright, *np.radians(SPIN_DEG))]
    return [T_motion, *(M for M in spins if turn_deg(M, T_motion) > GROUNDED_TURN_DEG)]


def _flat_turns(points: np.ndarray, T_motion: np.ndarray) -> list[np.ndarray]:
    """A flat part (a plate, a board) looks the same after a half turn about its face's normal or about either
    line across its face through its middle, so the registration may have settled on any of these: the motion
    composed with each, the least turn first (a plate laid down by a half turn too many turns the wrist round
    while the fingers hold it by its rim). Any other part: the motion alone."""
    normal = flat_normal(points)
    if normal is None:
        return [T_motion]
    middle = points.mean(axis=0)
    across = np.linalg.svd(points - middle, full_matrices=False)[2][:2]
    halves = [turn_about(middle, axis, np.pi) for axis in (normal, *across)]
    return sorted([T_motion, *(T_motion @ H for H in halves)], key=lambda M: turn_deg(M, np.eye(4)))


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
    """At the goal, per motion: a push's gripper against table and scene; a grasp's moved object against the scene
    and the height it is let go from (the lowest at which the gripper, holding and opened, clears both)."""

    def __init__(
        self,
        cfg: ContactConfig,
        robot: RobotModel,
        scene: np.ndarray,
        scene_tree: cKDTree | None,
        moved: list[np.ndarray],
        placing: _Placing,
    ) -> None:
        self.cfg, self.robot, self.scene, self.tree, self.placing = cfg, robot, scene, scene_tree, placing
        self.gripper = GripperBoxes(robot, cfg.collision_padding_m)
        self.clearance = cfg.collision_padding_m + CELL_MARGIN_M
        self.releasing = GripperBoxes(robot, self.clearance)
        self.moved = moved
        self.placed_reason = [self._placed_reason(m) for m in moved]

    def _placed_reason(self, moved: np.ndarray) -> str:
        if self.tree is None:
            return ""
        d, _ = self.tree.query(moved, distance_upper_bound=self.cfg.placed_clearance_m)
        return "placed object overlaps the scene" if np.isfinite(d).mean() > 0.02 else ""

    def _clear(self, T: np.ndarray, widths: tuple[float, ...], gripper: GripperBoxes | None = None) -> str:
        gripper = gripper or self.gripper
        for w in widths:
            if gripper.lowest_z(T, w) < 0.0:
                return "below the table"
            if gripper.hits_points(T, w, self.scene):
                return "hits the scene"
        return ""

    def _held_clear(self, held: Primitive, T_base_tcp: np.ndarray) -> bool:
        """The object's box in the hand at T_base_tcp keeps the gate's clearance from the scene."""
        if not len(self.scene):
            return True
        T_geom_base = np.linalg.inv(T_base_tcp @ held.T_link_geom)
        return not held.contains(transform_points(T_geom_base, self.scene)).any()

    def set_down(self, c: Candidate, T_goal: np.ndarray, k: int) -> np.ndarray:
        """The pose a grasp sets the object down from under the k-th motion: T_goal, or for a flat object laid on
        its face by a sideways gripper, T_goal turned to stand the object on the edge it tips over about."""
        if c.mode != "grasp" or not self.cfg.place_lifts_m:
            return T_goal
        tip = tip_turn(T_goal, self.moved[k])
        return T_goal if tip is None else tip @ T_goal

    def ending(self, c: Candidate, T_goal: np.ndarray, k: int) -> tuple[list[tuple[float, ...]], str]:
        """(the sets of set-down heights above T_goal it can end with, lowest first, why the candidate cannot end at
        T_goal under the k-th motion): a push ends at T_goal (one empty set); a grasp lets go at a release height
        above its set-down pose (set_down), config.place_lifts_m[0] or up to config.max_drop_m higher in
        DROP_STEP_M steps, each where the gripper clears the scene, and passes config.place_lifts_m's others raised
        as much (without place lifts: the object is set down at T_goal itself). Higher ones are kept for when the
        arm cannot take the lowest (a can stood up by its middle holds the hand sideways, the wrist low). The
        reason is empty when it can end there."""
        if c.mode != "grasp":
            why = self._clear(T_goal, (0.0,))
            return [()], f"gripper {why} at the goal" if why else ""
        if self.placed_reason[k]:
            return [], self.placed_reason[k]
        lifts = self.cfg.place_lifts_m
        if not lifts:  # set down at the goal itself
            why = self._clear(T_goal, (c.object_width_m,))
            return [()], f"gripper {why} at the goal" if why else ""
        widths = (c.object_width_m, _open_width(c, self.cfg, self.robot))
        p = self.placing
        held = held_box(p.points, c.T_contact, tcp_link=p.tcp_link, name=p.name).padded(self.clearance)
        first, out = "", []
        T_set = self.set_down(c, T_goal, k)
        for extra in np.arange(0.0, self.cfg.max_drop_m + 1e-9, DROP_STEP_M):
            T = T_set.copy()
            T[2, 3] += lifts[0] + extra
            why = self._clear(T, widths, self.releasing)
            if not why and not self._held_clear(held, T):
                why = "holds the object against the scene"
            if why:
                first = first or why
            else:
                out.append(tuple(h + float(extra) for h in lifts))
        return out, "" if out else f"gripper {first} at every release height"

    def release_width(self, c: Candidate, T_release: np.ndarray, free) -> float:
        """A grasp's widest finger gap, from the gripper's widest down to the approach's opening, whose fingers at
        the release clear the table and the scene by the gate's margin, with joints `free` accepts (None: any); the
        approach's opening when none wider does (ending() checked it), and a push's."""
        narrowest = _open_width(c, self.cfg, self.robot)
        if c.mode != "grasp":
            return narrowest
        for w in np.arange(self.robot.spec.gripper.max_width_m, narrowest, -RELEASE_WIDTH_STEP_M):
            if not self._clear(T_release, (float(w),), self.releasing) and (free is None or free(float(w))):
                return float(w)
        return narrowest

    def least_drop(self, c: Candidate, motions: list[np.ndarray]) -> tuple[float, str]:
        """(the least height beyond place_lifts_m[0] the object is let go from under any motion, "") or (0, the
        first motion's reason) when the candidate can end under none of them."""
        endings = [self.ending(c, _goal(c, M), k) for k, M in enumerate(motions)]
        lifts = [h[0][0] - (self.cfg.place_lifts_m or (0.0,))[0] for h, why in endings if not why and h[0]]
        if any(not why for _, why in endings):
            return (min(lifts) if lifts else 0.0), ""
        return 0.0, endings[0][1]


def _goal(c: Candidate, T_motion: np.ndarray) -> np.ndarray:
    return T_motion @ c.T_contact if c.T_goal is None else c.T_goal


def _open_width(c: Candidate, cfg: ContactConfig, robot: RobotModel) -> float:
    if c.mode != "grasp":
        return robot.spec.gripper.min_width_m
    return min(robot.spec.gripper.max_width_m, c.object_width_m + 2 * (cfg.finger_clearance_m + c.sway_m))


def _pre_contact(c: Candidate, distance_m: float) -> np.ndarray:
    """The contact pose backed off by distance_m: up its approach axis, or along the candidate's own direction."""
    out = c.T_contact.copy()
    out[:3, 3] += distance_m * (-c.T_contact[:3, 2] if c.back_off is None else c.back_off)
    return out


def _drop(plan: ContactPlan, cfg: ContactConfig) -> float:
    """How much higher than place_lifts_m[0] above its goal the plan lets the object go (0 for a push)."""
    if not plan.T_place or not cfg.place_lifts_m:
        return 0.0
    T_set = plan.T_goal if plan.T_set is None else plan.T_set
    return float(plan.T_place[0][2, 3] - T_set[2, 3] - cfg.place_lifts_m[0])


def _turn_rad(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.arccos(np.clip((np.trace(R_a.T @ R_b) - 1.0) / 2.0, -1.0, 1.0)))


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
    """What a grasp plan's held box is made of: the object's points, its name and the TCP link; and the world its
    release is checked in (None: the approach's)."""

    points: np.ndarray
    name: str
    tcp_link: str
    release_world: object = None


def _reachable_plans(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    seed: np.ndarray,
    motions: list[np.ndarray],
    goal_check: _GoalCheck,
    world,
    placing: _Placing,
    at_goal: bool = True,
    higher: bool = False,
) -> list[ContactPlan]:
    """The candidate's plan for each wrist twin whose poses all have IK (under the first object motion that has),
    the twin nearer the hand's present turn first: the other may be half a turn of joint 7 away, where a path is
    long and often not found, or be the one whose lines the arm can follow; else _Unreachable with why the
    candidate fails (the first twin tried)."""
    R_now = robot.tcp_pose(seed)[:3, :3]
    twins = sorted((c, _half_turn(c)), key=lambda t: _turn_rad(R_now, t.T_contact[:3, :3]))
    plans, first = [], None
    for twin in twins:
        try:
            accepts = _Acceptance(twin, cfg, robot, world, placing)
            plans.append(_twin_plan(twin, cfg, robot, seed, motions, goal_check, accepts, placing, at_goal, higher))
        except _Unreachable as e:
            first = first or e
    if not plans:
        raise first
    return plans


class _Acceptance:
    """Which IK solutions a twin's poses accept, in the gate's scene (collision_world; none: every solution).

    approach: the pre-contact, contact and arc poses, free with the fingers at the approach opening; goal: the goal
    pose itself, free of self-collision, workspace and keep-out (the object is set down from above it: a grasp
    with place lifts falls back to it only as a seed, _goal_ik); place: a
    grasp's release and the pose above it, free of everything, the object in the hand (the carry's world), the
    fingers holding it and opened to let go."""

    def __init__(self, c: Candidate, cfg: ContactConfig, robot: RobotModel, world, placing: _Placing) -> None:
        self.c, self.world, self.placing = c, world, placing
        self.width = _open_width(c, cfg, robot)
        self._carrying: CollisionWorld | None = None

    def approach(self, q: np.ndarray) -> bool:
        return not self.world.in_collision(q, self.width)

    def goal(self, q: np.ndarray) -> bool:
        return all(k.kind == "collision" for k in self.world.check(q, self.width))

    def place(self, q: np.ndarray) -> bool:
        if self._carrying is None:
            p = self.placing
            held = held_box(p.points, self.c.T_contact, tcp_link=p.tcp_link, name=p.name)
            self._carrying = (p.release_world or self.world).holding(held)
        return not any(self._carrying.in_collision(q, w) for w in (self.c.object_width_m, self.width))

    def released(self, q: np.ndarray):
        """Which finger gaps the joints q (the release's) accept opened in the gate's scene (None: any)."""
        return None if self.world is None else lambda w: not self.world.in_collision(q, w)

    def of(self, what: str):
        return None if self.world is None else getattr(self, what)


def _twin_plan(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    seed: np.ndarray,
    motions: list[np.ndarray],
    goal_check: _GoalCheck,
    accepts: _Acceptance,
    placing: _Placing,
    at_goal: bool = True,
    higher: bool = False,
) -> ContactPlan:
    """The plan of this twin under the first motion whose goal passes the goal checks and has IK (at_goal False:
    whose release and the pose above it have IK, the goal pose itself a seed only, _goal_ik), let go at the lowest
    release (higher: at the lowest of those that have); else _Unreachable."""
    T_pre = _pre_contact(c, cfg.pre_distance_m)
    qs = []
    arc = [(T, "arc") for T in c.via]
    for T, where in ((T_pre, "pre-contact"), (c.T_contact, "contact"), *arc):
        r = robot.ik(T, qs[-1] if qs else seed, settings=IK_SETTINGS, accept=accepts.of("approach"))
        if not r.success:
            raise _Unreachable(f"{where} pose {_why_no_ik(robot, T, qs[-1] if qs else seed, accepts.of('approach'))}")
        qs.append(r.q)
    first = ""
    for k in _turns_to_try(c, motions, robot):
        M = motions[k]
        T_goal = _goal(c, M)
        heights, why = goal_check.ending(c, T_goal, k)
        if why:
            continue
        T_set = goal_check.set_down(c, T_goal, k)
        for lifts in heights if higher else heights[:1]:
            goal, why = _goal_ik(robot, T_set, lifts, qs[-1], accepts, at_goal)
            if goal:
                break
        if goal:
            release = goal[1] if len(goal) > 1 else goal[0]  # (pose, joints) where the fingers let go
            width = goal_check.release_width(c, release[0], accepts.released(release[1]))
            plan = _plan(c, cfg, robot, T_pre, M, qs, goal, placing, width)
            return plan if T_set is T_goal else replace(plan, T_goal=T_goal, T_set=T_set)
        first = first or why
    raise _Unreachable(first or "goal pose out of reach")


def _why_no_ik(robot: RobotModel, T: np.ndarray, seed: np.ndarray, accept) -> str:
    """Why no IK solution for T was accepted: none reaches it, or every one found collides (an operator reading
    "out of reach" for an arm that reaches the pose but hits a neighbour or itself looks in the wrong place)."""
    if accept is None or not robot.ik(T, seed, settings=IK_SETTINGS).success:
        return "out of reach"
    return "reached only in collision"


def _turns_to_try(c: Candidate, motions: list[np.ndarray], robot: RobotModel) -> list[int]:
    """The motions (indices) to try for this contact: the grounded one, then up to MAX_TURNS_TRIED - 1 of the turns
    about a body's axis, those that leave the hand pointing most away from the robot's base first (a hand at the
    goal pointing back at the arm is one the arm cannot take)."""
    if len(motions) <= 1:
        return list(range(len(motions)))

    def away(k: int) -> float:
        T = _goal(c, motions[k])
        radial = T[:2, 3] / max(float(np.linalg.norm(T[:2, 3])), 1e-9)
        return float(T[:2, 2] @ radial)

    return [0, *sorted(range(1, len(motions)), key=away, reverse=True)[: MAX_TURNS_TRIED - 1]]


def _goal_ik(
    robot: RobotModel,
    T_goal: np.ndarray,
    lifts: tuple[float, ...],
    q_from: np.ndarray,
    accepts: _Acceptance,
    at_goal: bool = True,
) -> tuple[list[tuple[np.ndarray, np.ndarray]], str]:
    """(pose, IK) of the goal pose and of the poses `lifts` above it, each seeded by the last and drawn towards
    the contact's joints q_from (not home): a solution on another branch of the arm makes the carry swing it
    round, and what the fingers hold by friction alone (a plate by its rim) is flung out; ([], why) if one has
    none. at_goal False, for a grasp let go above its goal (it never takes the goal pose itself: a can stood up by
    its middle puts the wrist below the workspace floor there, its release higher does not): the poses above are
    solved from q_from, and the goal's joints, for the record only, from the release's without the gate's
    acceptance (the release's where it has none)."""
    poses = []
    for lift in (0.0, *lifts):
        T = T_goal.copy()
        T[2, 3] += lift
        poses.append(T)
    out = []
    for i, T in enumerate(poses):
        if i == 0 and not at_goal:
            continue
        accept = accepts.of("goal" if i == 0 else "place")
        seed = out[-1][1] if out else q_from
        r = robot.ik(T, seed, preferred_q=q_from, settings=GOAL_IK_SETTINGS, accept=accept)
        if not r.success:
            what = ("goal pose", "pose to let go from", "pose above the place")[min(i, 2)]
            held = " with the object in the hand" if i and accept is not None else ""
            return [], f"{what} out of reach{held}"
        out.append((T, r.q))
    if len(lifts) > 1:  # the arm reaches the release down the line from the pose above it, not by its own IK
        k = len(out) - len(lifts)
        q_release = _descent(robot, out[k + 1][1], out[k + 1][0], out[k][0], accepts.of("place"))
        if q_release is None:
            return [], "descent to the pose to let go from blocked with the object in the hand"
        out[k] = (out[k][0], q_release)
    if not at_goal:
        q_release = out[0][1]
        r = robot.ik(poses[0], q_release, preferred_q=q_release, settings=GOAL_IK_SETTINGS)
        out.insert(0, (poses[0], r.q if r.success else q_release))
    return out, ""


def _descent(robot: RobotModel, q_above: np.ndarray, T_above: np.ndarray, T_release: np.ndarray, accept):
    """The joints the straight line from q_above (at T_above) arrives at T_release with, each step solved from the
    last as the manipulation's line is (motion.cartesian), every one accepted; None where a step has none or
    jumps. The release's own IK may lie on another branch of the arm than the line reaches: a can stood up far to
    the side had its release free and the line's end with link2 in the base."""
    steps = max(1, int(np.ceil(np.linalg.norm(T_release[:3, 3] - T_above[:3, 3]) / LINE_STEP_M)))
    q = q_above
    for s in np.linspace(0.0, 1.0, steps + 1)[1:]:
        T = T_release.copy()
        T[:3, 3] = (1.0 - s) * T_above[:3, 3] + s * T_release[:3, 3]
        r = robot.ik(T, q, preferred_q=q, settings=LINE_IK_SETTINGS, accept=accept)
        if not r.success or np.max(np.abs(r.q - q)) > LINE_JUMP_RAD:
            return None
        q = r.q
    return q


def _plan(
    c: Candidate,
    cfg: ContactConfig,
    robot: RobotModel,
    T_pre: np.ndarray,
    T_motion: np.ndarray,
    qs: list[np.ndarray],
    goal: list[tuple[np.ndarray, np.ndarray]],
    placing: _Placing,
    release_width: float,
) -> ContactPlan:
    """qs: the pre-contact, contact and arc joints; goal: (pose, joints) at the goal and the place lifts;
    release_width: a grasp's finger gap to let go with (a push's: its opening)."""
    (T_goal, q_goal), *place = goal
    margin = min(float(np.min(np.minimum(q - robot.lower, robot.upper - q))) for q in [*qs, q_goal])
    reach = float(np.clip(margin / 0.5, 0.0, 1.0))
    scores = {"antipodal": c.antipodal, "centred": c.centred, "approach": c.approach, "reach": reach}
    w = cfg.weights
    total = sum(w[k] * v for k, v in scores.items()) / sum(w.values())
    grasp = c.mode == "grasp"
    closing = c.object_width_m if c.grip_width_m is None else c.grip_width_m
    width = robot.spec.gripper.min_width_m if not grasp else max(0.0, closing - cfg.squeeze_m)
    q_pre, q_contact, *q_via = qs
    return ContactPlan(
        mode=c.mode,
        T_pre=T_pre,
        T_contact=c.T_contact,
        T_goal=T_goal,
        T_motion=T_motion,
        width_m=width,
        open_width_m=_open_width(c, cfg, robot),
        release_width_m=release_width,
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
