"""The simulator's truth of a run, recorded beside verification's own measurement so benches and tests can check
it: where every object is at the run's two captures (an object's centre is the mean of its shapes' centres, on
the axis of a body of revolution, so an unseen turn about that axis does not move it), how the moved object is
turned against the goal (up to the turns its shape does not show) and each hinge's angle; for a sweep, a lift or
a take-off, whether the task is done as the task defines it (tasks.py).

Attach it to the stages (PipelineStages(listeners=[SimTruth()])) on the sim only; it never decides a run.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from drivers.sim.gl import mujoco
from drivers.sim.scene import SceneObject
from drivers.sim.world import SimWorld
from pipeline.reasoning.instruction import parse_instruction
from runtime.run.context import RunContext
from runtime.run.summary import SimTruthRecord
from runtime.sim_truth.tasks import task_truth

SAME_SIZE_M = 0.005  # box sides this close are the same: a turn swapping them does not show


@dataclass(frozen=True)
class WorldState:
    """Every object's centre and its main shape's orientation (base frame), and every hinge's angle [deg]."""

    centres: dict[str, np.ndarray]
    frames: dict[str, np.ndarray]
    hinges: dict[str, float]


def world_state(world: SimWorld) -> WorldState:
    m, d = world.model, world.data
    centres, frames, hinges = {}, {}, {}
    with world.lock:
        for o in world.scene.objects:
            root = m.body(o.name).id
            centres[o.name] = d.geom_xpos[np.flatnonzero(m.body_rootid[m.geom_bodyid] == root)].mean(axis=0)
            frames[o.name] = d.geom(f"{o.name}_g0").xmat.reshape(3, 3).copy()
            for j in np.flatnonzero(m.body_rootid[m.jnt_bodyid] == root):
                if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:  # an object's part: a lid
                    hinges[m.joint(j).name] = float(np.degrees(d.qpos[m.jnt_qposadr[j]]))
    return WorldState(centres, frames, hinges)


def _box_turns(size: tuple[float, float, float]) -> list[np.ndarray]:
    """The turns of a box (its own frame) that look the same: the 24 axis permutations with signs (proper
    rotations) that map every side onto one of its own length."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            S = np.zeros((3, 3))
            S[list(perm), range(3)] = signs
            if np.linalg.det(S) > 0 and all(abs(size[perm[i]] - size[i]) <= SAME_SIZE_M for i in range(3)):
                out.append(S)
    return out


def turn_error_deg(o: SceneObject, R_want: np.ndarray, R_now: np.ndarray) -> float:
    """How far the object's shape is turned from where it should be, up to the turns its shape does not show: none
    of a ball, those about the axis of a body of revolution (end for end too for a plain cylinder or a plate),
    a box's that swap sides of one length; every turn of anything else."""
    if o.kind == "sphere":
        return 0.0
    if o.kind in ("cylinder", "bottle", "plate", "bowl"):
        cos = float(R_want[:, 2] @ R_now[:, 2])
        cos = abs(cos) if o.kind in ("cylinder", "plate") else cos
        return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    turns = _box_turns(o.size_m) if o.kind in ("box", "platform") and o.size_m else [np.eye(3)]
    return min(float(np.degrees(Rotation.from_matrix(R_now.T @ R_want @ S).magnitude())) for S in turns)


def tilt_error_deg(o: SceneObject, R_want: np.ndarray, R_now: np.ndarray) -> float:
    """How far the object is tipped from the goal's pose (which way up it stands), up to the same symmetric turns;
    a turn about the vertical is no tip."""
    if o.kind in ("sphere", "cylinder", "bottle", "plate", "bowl"):
        return turn_error_deg(o, R_want, R_now)  # a body of revolution's only visible turn tips its axis
    up = np.array([0.0, 0.0, 1.0])
    turns = _box_turns(o.size_m) if o.kind in ("box", "platform") and o.size_m else [np.eye(3)]
    now = R_now.T @ up
    return min(float(np.degrees(np.arccos(np.clip(now @ ((R_want @ S).T @ up), -1.0, 1.0)))) for S in turns)


def truth_of(
    ctx: RunContext, *, before: WorldState, after: WorldState, objects: dict[str, SceneObject]
) -> SimTruthRecord:
    """How far every object moved, and for a whole object that was moved (not a hinged part, whose truth is its
    hinge angle), how far its centre ended from where the goal motion puts it, and how far it is turned from the
    goal's turn."""
    moved = {n: float(np.linalg.norm(after.centres[n] - before.centres[n])) for n in before.centres}
    motion, goal = ctx.motion, ctx.goal
    hinged = goal is not None and goal.mask_anchor is not None
    if not moved or hinged or motion is None or motion.T_base_camera is None:
        return SimTruthRecord(object_displacement_m=moved, hinge_deg=after.hinges)
    name = max(moved, key=moved.get)
    T = motion.T_base
    error = float(np.linalg.norm(after.centres[name] - (T[:3, :3] @ before.centres[name] + T[:3, 3])))
    o, R_want, R_now = objects[name], T[:3, :3] @ before.frames[name], after.frames[name]
    return SimTruthRecord(
        object_displacement_m=moved,
        hinge_deg=after.hinges,
        target=name,
        target_goal_error_m=error,
        target_turn_error_deg=round(turn_error_deg(o, R_want, R_now), 2),
        target_tilt_error_deg=round(tilt_error_deg(o, R_want, R_now), 2),
    )


class SimTruth:
    """A capture listener: the objects' centres at every capture, and at the one after execution the truth into the
    record, against the capture the executed plan was made from (ctx.basis: the first, or a second look's)."""

    def __init__(self) -> None:
        self._states: dict[str, WorldState] = {}

    def on_capture(self, name: str, ctx: RunContext) -> None:
        world = ctx.devices.world
        if world is None:
            raise RuntimeError("SimTruth listens to simulated runs only (devices.world is None)")
        state = world_state(world)
        if name == "after":
            objects = {o.name: o for o in world.scene.objects}
            truth = truth_of(ctx, before=self._states[ctx.basis], after=state, objects=objects)
            try:
                instr = parse_instruction(ctx.instruction)
            except ValueError:
                instr = None
            task = task_truth(world, instr) if instr is not None else None
            ctx.record.summary.sim_truth = truth.model_copy(update={"task": task}) if task else truth
        else:
            self._states[name] = state
