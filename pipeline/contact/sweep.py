"""Sweeping a group of small parts into a container with a hand tool: the tool's grasp and the strokes.

The tool (tool.py: its head and handle) is grasped on its handle by the same grasp planning as any object
(planner.plan_contacts; from above, the fingers across the handle, clear of the head, nearest it first), which
also solves the poses it is put back from: where it was, released just above the table. The strokes push the
group into the container, straight in, as a person sweeps into a dustpan:
  direction the group's motion (the group centroid's translation, pipeline.grounding.group) finds the container's
            far wall; the strokes run perpendicular to it (along the side walls), or along the motion when the
            container shows no straight far wall
  lanes     the group's width across the strokes, split into as few lanes as the head's width (less a margin
            each side) covers; each starts with the head's front edge behind the group's nearest part
  end       the head's front edge stops short of the container's far wall, between its side walls: a lane beside
            the opening slants in, the tool (all its length between the walls) turned with it
  height    the tool level, its lowest point `clearance_m` above the table (over a dustpan's lip and floor)
  travel    between strokes the tool rises to `travel_m` and goes back over the group
  passes    the lanes are swept `passes` times, as a person sweeps again what slid past the head's edge
The tool keeps its grasp and its level all along: a stroke pose is the grasp pose turned about the vertical so
the head leads, and shifted so the head's front edge is where the stroke puts it.

Refusals, each with the numbers: the motion has no horizontal part; the container's wall faces the group (it opens
away from it); the head does not fit between the container's walls; a lane would slant more than `max_turn_deg`
to end between them; another object stands in a lane; the group is wider than `max_strokes` lanes; the handle has no
reachable grasp; no grasp reaches every stroke pose collision-free (the tool held, checked with its own margin).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from pipeline.contact.gripper import GripperBoxes
from pipeline.contact.planner import IK_SETTINGS, plan_contacts
from pipeline.contact.tool import ToolError, ToolShape, tool_box, tool_shape
from pipeline.contact.types import ContactConfig, ContactPlan
from safety.collision import CollisionWorld
from safety.geometry import Primitive
from safety.robot_model import RobotModel

LIFT_M = 0.10  # the tool is lifted this far after the grasp (motion.manipulation.phases.LIFT_M)
MAX_GRASP_SKEW_DEG = 20.0  # the fingers close across the handle, at most this far off square to it


@dataclass(frozen=True)
class SweepConfig:
    """Stroke geometry [m, deg]; the defaults suit a hand brush and a dustpan."""

    start_gap_m: float = 0.02  # head's front edge behind the group's nearest part at a stroke's start
    wall_gap_m: float = 0.025  # head's front edge short of the container's far wall at its end (1 cm cells)
    side_gap_m: float = 0.02  # head clear of the container's side walls (the gate sees points as 1 cm cells)
    clearance_m: float = 0.004  # the tool's lowest point above the table along a stroke
    travel_m: float = 0.07  # the tool's lowest point above the table between strokes
    edge_margin_m: float = 0.015  # of the head's width, each side, not counted on to carry parts along ...
    overhang_m: float = 0.01  # ... and the lanes reach this far beyond the group's outermost seen points
    tool_padding_m: float = 0.002  # the held tool's margin in the gate while it touches or skims (robot: padding_m)
    release_m: float = 0.006  # the tool is released this far above where it lay
    wall_height_m: float = 0.01  # container points this high above the table are its walls
    obstacle_height_m: float = 0.01  # other points this high in a lane stand in the way
    max_strokes: int = 4  # lanes
    passes: int = 2  # every lane swept this many times: a part that slid off the head's edge is caught again
    max_turn_deg: float = 35.0  # strokes run at most this far off the motion (square to the far wall, or slanting in)
    min_motion_m: float = 0.03


class SweepRefused(RuntimeError):
    """The group cannot be swept as asked; the message says why."""


@dataclass(frozen=True)
class Stroke:
    """One stroke: down behind the group, along to the container, up; TCP poses (base frame) and their joints."""

    T_above_start: np.ndarray
    T_start: np.ndarray
    T_end: np.ndarray
    T_above_end: np.ndarray
    q_above_start: np.ndarray
    q_start: np.ndarray
    q_end: np.ndarray
    q_above_end: np.ndarray


@dataclass(frozen=True, kw_only=True)
class SweepPlan:
    """A sweep decision, from contact planning to execution (motion.manipulation.sweep reads it): the tool's
    grasp (as a grasp ContactPlan would carry it), the strokes, and the poses the tool is put back from."""

    mode: str = "sweep"
    T_pre: np.ndarray  # above the tool's grasp
    T_contact: np.ndarray  # the grasp on the handle
    q_pre: np.ndarray
    q_contact: np.ndarray
    width_m: float
    open_width_m: float
    held: Primitive  # the whole tool in the TCP frame
    strokes: tuple[Stroke, ...]
    T_place: tuple[np.ndarray, np.ndarray]  # put back: release pose, the pose above it
    q_place: tuple[np.ndarray, np.ndarray]
    T_motion: np.ndarray  # the group's motion (x_goal = T x_init, base frame)
    tool_padding_m: float
    lanes_m: tuple[float, ...] = ()  # each stroke's lateral offset from the group's middle, at its start
    score: float = 0.0
    source: str = "pipeline.contact.sweep"
    rejected: dict[str, int] = field(default_factory=dict)

    @property
    def T_goal(self) -> np.ndarray:
        return self.strokes[-1].T_end

    @property
    def via(self) -> tuple[np.ndarray, ...]:
        return ()


@dataclass(frozen=True)
class _Frame:
    """Table coordinates of a sweep: s along the motion, l across it (to its left), from the group's centroid."""

    origin: np.ndarray
    d: np.ndarray
    n: np.ndarray

    def s(self, p: np.ndarray) -> np.ndarray:
        return (np.atleast_2d(p)[:, :2] - self.origin[:2]) @ self.d[:2]

    def l(self, p: np.ndarray) -> np.ndarray:  # noqa: E743
        return (np.atleast_2d(p)[:, :2] - self.origin[:2]) @ self.n[:2]

    def point(self, s: float, l: float, z: float = 0.0) -> np.ndarray:  # noqa: E741
        p = self.origin + s * self.d + l * self.n
        return np.array([p[0], p[1], z])


@dataclass(frozen=True)
class _Lane:
    start: np.ndarray  # the head's front edge (base frame, on the table) at the stroke's start
    end: np.ndarray  # ... and at its end
    lateral_m: float


def plan_sweep(
    group: np.ndarray,
    tool: np.ndarray,
    container: np.ndarray,
    scene: np.ndarray,
    T_motion: np.ndarray,
    robot: RobotModel,
    *,
    contact: ContactConfig,
    sweep: SweepConfig | None = None,
    safety_config=None,
    q_seed: np.ndarray | None = None,
    viewpoint: np.ndarray | None = None,
    tool_name: str = "tool",
) -> SweepPlan:
    """The first sweep whose tool grasp and strokes are all reachable and collision-free, or SweepRefused.

    group, tool, container: their seen points (base frame); scene: everything else the gate sees (the container
    included, the group and the tool not). T_motion: the group's motion (base frame). contact: the grasp settings
    the run uses (min TCP height, padding, ...). safety_config: the gate's (padding, workspace) for the IK checks.
    """
    cfg = sweep or SweepConfig()
    try:
        shape = tool_shape(tool)
    except ToolError as e:
        raise SweepRefused(f"the {tool_name}: {e}") from e
    group = np.asarray(group, dtype=np.float64).reshape(-1, 3)
    shift = T_motion[:2, 3] + (T_motion[:2, :2] - np.eye(2)) @ group[:, :2].mean(axis=0)
    if np.linalg.norm(shift) < cfg.min_motion_m:
        raise SweepRefused(
            f"the group's goal is {np.linalg.norm(shift) * 1000:.0f} mm from where it is (need "
            f"{cfg.min_motion_m * 1000:.0f} mm along the table to sweep it)"
        )
    d = _into(container, group, shift, cfg)
    frame = _Frame(np.array([*group[:, :2].mean(axis=0), 0.0]), d, np.array([-d[1], d[0], 0.0]))
    lanes = _lanes(group, container, scene, frame, shape, cfg, float(shift @ d[:2]))
    return _reachable(
        shape, lanes, group, scene, T_motion, robot, contact, cfg, safety_config, q_seed, viewpoint, tool_name
    )


def _into(container: np.ndarray, group: np.ndarray, shift: np.ndarray, cfg: SweepConfig) -> np.ndarray:
    """The strokes' direction: square to the container's far wall (the line through its wall points beyond the
    group's goal, along the motion), or the motion's own when there is no such straight wall."""
    d = shift / np.linalg.norm(shift)
    walls = container[container[:, 2] > cfg.wall_height_m, :2]
    s = (walls - group[:, :2].mean(axis=0)) @ d
    far = walls[s > np.linalg.norm(shift)]
    if len(far) >= 10:
        centred = far - far.mean(axis=0)
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        if sv[1] < 0.2 * sv[0]:  # a straight wall
            normal = np.array([-vt[0][1], vt[0][0]])
            normal = normal if normal @ d > 0 else -normal
            if np.degrees(np.arccos(np.clip(normal @ d, -1.0, 1.0))) <= cfg.max_turn_deg:
                d = normal
    return np.array([d[0], d[1], 0.0])


def _lanes(
    group: np.ndarray,
    container: np.ndarray,
    scene: np.ndarray,
    f: _Frame,
    shape: ToolShape,
    cfg: SweepConfig,
    distance: float,
) -> list[_Lane]:
    """The strokes' head positions at their starts and ends, or SweepRefused."""
    gs, gl = f.s(group), f.l(group)
    walls = container[container[:, 2] > cfg.wall_height_m]
    ws, wl = f.s(walls), f.l(walls)
    half = shape.head_width_m / 2
    reach = half - cfg.edge_margin_m  # half the lane one stroke clears
    group_front = float(np.percentile(gs, 99))
    # a wall between the group and its goal, across the way the head would pass: the container opens elsewhere
    facing = (ws > group_front) & (ws < distance) & (np.abs(wl) < reach)
    if facing.sum() > 3:
        s_wall = float(np.percentile(ws[facing], 5))
        raise SweepRefused(
            f"the container's wall stands {s_wall * 1000:.0f} mm ahead of the group, across its way (the group is "
            f"to move {distance * 1000:.0f} mm): the container opens away from it"
        )
    beyond = (ws > distance - 0.01) & (np.abs(wl) < half + 0.02)
    far = float(np.percentile(ws[beyond], 5)) if beyond.sum() > 3 else float(np.percentile(f.s(container), 98))
    s_end = far - cfg.wall_gap_m
    inner = (ws > group_front) & (ws < far - 0.005)
    left = wl[inner & (wl > 0)]
    right = wl[inner & (wl < 0)]
    lo = float(right.max()) + cfg.side_gap_m + half if len(right) else -np.inf
    hi = float(left.min()) - cfg.side_gap_m - half if len(left) else np.inf
    if lo > hi:
        raise SweepRefused(
            f"the tool's head ({shape.head_width_m * 1000:.0f} mm) does not fit between the container's walls "
            f"({(float(left.min()) - float(right.max())) * 1000:.0f} mm apart, {cfg.side_gap_m * 1000:.0f} mm kept "
            "each side)"
        )
    g_lo, g_hi = float(np.percentile(gl, 1)) - cfg.overhang_m, float(np.percentile(gl, 99)) + cfg.overhang_m
    count = max(1, int(np.ceil((g_hi - g_lo) / (2 * reach))))
    if count > cfg.max_strokes:
        raise SweepRefused(
            f"the group is {(g_hi - g_lo) * 1000:.0f} mm wide across the motion: {count} strokes of the "
            f"{2 * reach * 1000:.0f} mm the head clears (at most {cfg.max_strokes})"
        )
    centres = [0.5 * (g_lo + g_hi)] if count == 1 else list(np.linspace(g_lo + reach, g_hi - reach, count))
    s_start = float(np.percentile(gs, 1)) - cfg.start_gap_m
    if s_end - s_start < 0.02:
        raise SweepRefused(f"the container's far wall is {(s_end - s_start) * 1000:.0f} mm beyond the group's back")
    walls_length = float(far - ws[inner].min()) if inner.any() else 0.0
    lanes = []
    for c in centres:  # a lane beside the opening slants in; the tool then lies aslant between the walls
        end = float(np.clip(c, lo, hi))
        for _ in range(4):
            slant = np.arctan2(abs(c - end), s_end - s_start)
            end = float(np.clip(c, lo + walls_length * np.sin(slant), hi - walls_length * np.sin(slant)))
        slant = np.degrees(np.arctan2(abs(c - end), s_end - s_start))
        if slant > cfg.max_turn_deg or lo + walls_length * np.sin(np.radians(slant)) > hi:
            raise SweepRefused(
                f"a stroke {c * 1000:+.0f} mm across the group's middle would slant {slant:.0f} deg to end between the "
                f"container's walls (at most {cfg.max_turn_deg:.0f})"
            )
        corner = (half + cfg.side_gap_m / 2) * np.sin(np.radians(slant))  # a slanted head's corner leads
        lanes.append(_Lane(f.point(s_start, c), f.point(s_end - corner, end), c))
    _check_lanes_free(lanes, container, scene, shape, cfg)
    return lanes


def _check_lanes_free(
    lanes: list[_Lane], container: np.ndarray, scene: np.ndarray, shape: ToolShape, cfg: SweepConfig
) -> None:
    """SweepRefused when another object's points stand where the head passes."""
    others = scene[scene[:, 2] > cfg.obstacle_height_m]
    if len(container) and len(others):
        near, _ = cKDTree(container).query(others, distance_upper_bound=0.01)
        others = others[~np.isfinite(near)]
    if not len(others):
        return
    half = shape.head_width_m / 2 + cfg.tool_padding_m
    for k, lane in enumerate(lanes, start=1):
        u = lane.end[:2] - lane.start[:2]
        length = float(np.linalg.norm(u))
        u /= length
        q = others[:, :2] - lane.start[:2]
        along, across = q @ u, q @ np.array([-u[1], u[0]])
        hit = (along > -shape.head_depth_m) & (along < length) & (np.abs(across) < half)
        if hit.any():
            p = others[hit].mean(axis=0)
            raise SweepRefused(
                f"stroke {k}: {hit.sum()} points of another object stand in the head's way, about "
                f"({p[0]:.2f}, {p[1]:.2f}) m, up to {others[hit, 2].max() * 1000:.0f} mm high"
            )


def _reachable(
    shape: ToolShape,
    lanes: list[_Lane],
    group: np.ndarray,
    scene: np.ndarray,
    T_motion: np.ndarray,
    robot: RobotModel,
    contact: ContactConfig,
    cfg: SweepConfig,
    safety_config,
    q_seed: np.ndarray | None,
    viewpoint: np.ndarray | None,
    tool_name: str,
) -> SweepPlan:
    """The first ranked grasp of the handle whose strokes all have collision-free IK with the tool held."""
    lifts = (cfg.release_m, cfg.release_m + LIFT_M)
    # every reachable grasp (not the few best): the one nearest the head is wanted, whatever its score
    grasp_config = contact.model_copy(
        update={"place_lifts_m": lifts, "side_approach_deg": (), "lean_deg": 0.0, "keep": contact.ik_candidates}
    )
    others = np.vstack([scene, group]) if len(group) else scene
    world = CollisionWorld(robot, safety_config, points=np.vstack([others, shape.head]), table=False)
    # the tool is put back with its own margin, its head no obstacle: the head is part of what the hand holds
    release = CollisionWorld(robot, safety_config, points=others, table=False, held_padding_m=cfg.tool_padding_m)
    result = plan_contacts(
        shape.handle,
        others,
        np.eye(4),
        robot,
        mode="grasp",
        config=grasp_config,
        q_seed=q_seed,
        collision_world=world,
        viewpoint=viewpoint,
        object_name=tool_name,
        release_world=release,
    )
    if not result.ok:
        raise SweepRefused(f"the {tool_name}'s handle cannot be grasped: {result.reason}")
    rejected: Counter[str] = Counter()
    gripper = GripperBoxes(robot, contact.collision_padding_m)
    # nearest the head first: the head carries the tool's weight, which turns it in a grasp far from it
    for plan in sorted(result.plans, key=lambda p: float(np.linalg.norm(p.T_contact[:2, 3] - shape.front[:2]))):
        if plan.T_contact[2, 2] > -0.95:
            rejected["grasp not from above"] += 1
            continue
        if abs(plan.T_contact[:3, 1] @ shape.axis) > np.sin(np.radians(MAX_GRASP_SKEW_DEG)):
            rejected["fingers not across the handle"] += 1
            continue
        if any(gripper.hits_points(T, plan.open_width_m, shape.head) for T in (plan.T_pre, plan.T_contact)):
            rejected["fingers on the head"] += 1
            continue
        try:
            strokes = _strokes(plan, shape, lanes, scene, robot, cfg, safety_config, tool_name) * cfg.passes
        except _Unreachable as e:
            rejected[e.reason] += 1
            continue
        return SweepPlan(
            T_pre=plan.T_pre,
            T_contact=plan.T_contact,
            q_pre=plan.q_pre,
            q_contact=plan.q_contact,
            width_m=plan.width_m,
            open_width_m=plan.open_width_m,
            held=tool_box(shape, plan.T_contact, tcp_link=robot.tcp_frame, name=tool_name),
            strokes=strokes,
            T_place=(plan.T_place[0], plan.T_place[1]),
            q_place=(plan.q_place[0], plan.q_place[1]),
            T_motion=T_motion,
            tool_padding_m=cfg.tool_padding_m,
            lanes_m=tuple(lane.lateral_m for lane in lanes),
            score=plan.score,
            rejected=dict(rejected),
        )
    counts = ", ".join(f"{n} {why}" for why, n in rejected.most_common())
    raise SweepRefused(f"no grasp of the {tool_name} reaches every stroke ({len(result.plans)} grasps: {counts})")


class _Unreachable(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def stroke_pose(T_grasp: np.ndarray, shape: ToolShape, direction: np.ndarray, front: np.ndarray) -> np.ndarray:
    """The TCP pose that holds the tool (grasped at T_grasp as it lay) level, its head leading along `direction`,
    the head's front edge at `front` (base frame): the grasp turned about the vertical and shifted."""
    a, b = shape.axis[:2], direction[:2] / np.linalg.norm(direction[:2])
    turn = np.arctan2(a[0] * b[1] - a[1] * b[0], a @ b)
    R = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R @ T_grasp[:3, :3]
    T[:3, 3] = front - R @ (shape.front - T_grasp[:3, 3])
    return T


def _strokes(
    plan: ContactPlan,
    shape: ToolShape,
    lanes: list[_Lane],
    scene: np.ndarray,
    robot: RobotModel,
    cfg: SweepConfig,
    safety_config,
    tool_name: str,
) -> tuple[Stroke, ...]:
    """Each lane's stroke poses, solved in the gate's sweeping world (the tool held with its own margin, the
    group not there: it is what the tool pushes); _Unreachable naming the first pose without a solution."""
    held = tool_box(shape, plan.T_contact, tcp_link=robot.tcp_frame, name=tool_name)
    world = CollisionWorld(
        robot, safety_config, points=scene, held=held, gripper_width_m=plan.width_m, held_padding_m=cfg.tool_padding_m
    )
    accept = lambda q: not world.in_collision(q, plan.width_m)  # noqa: E731
    up = np.array([0.0, 0.0, 1.0])
    out = []
    q = plan.q_contact
    for k, lane in enumerate(lanes, start=1):
        direction = lane.end - lane.start
        low = stroke_pose(plan.T_contact, shape, direction, lane.start + cfg.clearance_m * up)
        end = stroke_pose(plan.T_contact, shape, direction, lane.end + cfg.clearance_m * up)
        rise = (cfg.travel_m - cfg.clearance_m) * up
        poses = {"above the start": _raised(low, rise), "start": low, "end": end, "above the end": _raised(end, rise)}
        qs = []
        for what, T in poses.items():
            r = robot.ik(T, q, settings=IK_SETTINGS, accept=accept)
            if not r.success:
                raise _Unreachable(f"stroke {k} {what} out of reach with the tool held")
            q = r.q
            qs.append(q)
        out.append(Stroke(*poses.values(), *qs))
    return tuple(out)


def _raised(T: np.ndarray, by: np.ndarray) -> np.ndarray:
    out = T.copy()
    out[:3, 3] += by
    return out
