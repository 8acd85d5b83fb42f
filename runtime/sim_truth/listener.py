"""The simulator's truth of a run, recorded beside verification's own measurement so benches and tests can check
it: where every object is at the run's two captures (an object's centre is the mean of its shapes' centres, on
the axis of a body of revolution, so an unseen turn about that axis does not move it) and each hinge's angle;
for a sweep, a lift or a take-off, whether the task is done as the task defines it (tasks.py).

Attach it to the stages (PipelineStages(listeners=[SimTruth()])) on the sim only; it never decides a run.
"""

from __future__ import annotations

import numpy as np

from drivers.sim.gl import mujoco
from drivers.sim.world import SimWorld
from pipeline.reasoning.instruction import parse_instruction
from runtime.run.context import RunContext
from runtime.run.summary import SimTruthRecord
from runtime.sim_truth.tasks import task_truth


def object_centres(world: SimWorld) -> tuple[dict[str, np.ndarray], dict[str, float]]:
    """(each scene object's centre, base frame; each hinge joint's angle [deg])."""
    m, d = world.model, world.data
    centres, hinges = {}, {}
    with world.lock:
        for o in world.scene.objects:
            root = m.body(o.name).id
            centres[o.name] = d.geom_xpos[np.flatnonzero(m.body_rootid[m.geom_bodyid] == root)].mean(axis=0)
            for j in np.flatnonzero(m.body_rootid[m.jnt_bodyid] == root):
                if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:  # an object's part: a lid
                    hinges[m.joint(j).name] = float(np.degrees(d.qpos[m.jnt_qposadr[j]]))
    return centres, hinges


def truth_of(
    ctx: RunContext, *, before: dict[str, np.ndarray], after: dict[str, np.ndarray], hinges: dict[str, float]
) -> SimTruthRecord:
    """How far every object moved, and for a whole object that was moved (not a hinged part, whose truth is its
    hinge angle), how far its centre ended from where the goal motion puts it."""
    moved = {n: float(np.linalg.norm(after[n] - before[n])) for n in before}
    motion, goal = ctx.motion, ctx.goal
    hinged = goal is not None and goal.mask_anchor is not None
    if not moved or hinged or motion is None or motion.T_base_camera is None:
        return SimTruthRecord(object_displacement_m=moved, hinge_deg=hinges)
    name = max(moved, key=moved.get)
    T = motion.T_base
    error = float(np.linalg.norm(after[name] - (T[:3, :3] @ before[name] + T[:3, 3])))
    return SimTruthRecord(object_displacement_m=moved, hinge_deg=hinges, target=name, target_goal_error_m=error)


class SimTruth:
    """A capture listener: the objects' centres at the first capture, the truth into the record at the second."""

    def __init__(self) -> None:
        self._before: dict[str, np.ndarray] = {}

    def on_capture(self, name: str, ctx: RunContext) -> None:
        world = ctx.devices.world
        if world is None:
            raise RuntimeError("SimTruth listens to simulated runs only (devices.world is None)")
        centres, hinges = object_centres(world)
        if name == "capture":
            self._before = centres
        elif name == "after":
            truth = truth_of(ctx, before=self._before, after=centres, hinges=hinges)
            try:
                instr = parse_instruction(ctx.instruction)
            except ValueError:
                instr = None
            task = task_truth(world, instr) if instr is not None else None
            ctx.record.summary.sim_truth = truth.model_copy(update={"task": task}) if task else truth
