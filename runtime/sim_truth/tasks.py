"""The simulator's truth of the sweep, lift and take-off tasks, judged the way the tasks are defined.

  sweep     how many of the named parts (the scene's objects the target phrase names) have their centre over
            the container's floor (inside its walls, lip included; resting there, on it or on other parts, not
            higher than a part's length above the walls' top): done when at least 80 % are
  lift      the object touches nothing but the fingers and its lowest point is at least 1 cm above the table
            (the paper's "lifted clear"): done when both hold
  take off  the object touches neither its support nor anything but the table (and maybe the fingers) and
            rests on the table: done when the support is left empty that way
Objects are named as a person names them (drivers.sim.kinds: a noun and a colour), which is how the sentence
names them; a phrase that names no object, or several where one is meant, is recorded as not done, with why.
For benches and tests only; never used to decide a run.
"""

from __future__ import annotations

import math

import numpy as np

from drivers.sim.generate import family
from drivers.sim.gl import mujoco
from drivers.sim.kinds import NOUN_KINDS
from drivers.sim.scene import DUSTPAN_WALL_M, SceneObject
from drivers.sim.world import SimWorld
from pipeline.perception.offline_segmenter import parse_phrase
from pipeline.reasoning.instruction import Instruction
from runtime.run.summary import TaskTruthRecord

SWEPT_FRACTION = 0.8
CLEAR_M = 0.01
ON_TABLE_M = 0.01
UPRIGHT_TOL_DEG = 15.0  # a stood-up object's axis this close to vertical stands (the verification's turn tolerance)


def named(world: SimWorld, phrase: str) -> list[SceneObject]:
    """The scene's objects a phrase names (its noun's kinds, its colour's family)."""
    p = parse_phrase(phrase)
    kinds = NOUN_KINDS.get(p.shape or "", frozenset())
    return [
        o
        for o in world.scene.objects
        if (p.shape is None or o.kind in kinds) and (p.colour is None or family(o.color) == p.colour)
    ]


def _geoms(world: SimWorld, name: str) -> np.ndarray:
    m = world.model
    return np.flatnonzero(m.body_rootid[m.geom_bodyid] == m.body(name).id)


def lowest_point(world: SimWorld, name: str) -> float:
    """The lowest point of an object's geoms [m] (their bounding boxes, oriented)."""
    m, d = world.model, world.data
    low = np.inf
    for g in _geoms(world, name):
        R = d.geom_xmat[g].reshape(3, 3)
        half = m.geom_aabb[g, 3:]
        centre = d.geom_xpos[g] + R @ m.geom_aabb[g, :3]
        low = min(low, float(centre[2] - np.abs(R[2]) @ half))
    return low


def touching(world: SimWorld, name: str) -> set[str]:
    """The bodies (scene objects by name, 'table', robot links) an object's geoms are in contact with."""
    m, d = world.model, world.data
    own = set(_geoms(world, name).tolist())
    out = set()
    for c in d.contact[: d.ncon]:
        a, b = int(c.geom1), int(c.geom2)
        if (a in own) == (b in own):
            continue
        other = b if a in own else a
        body = m.body(m.body_rootid[m.geom_bodyid[other]]).name
        out.add(body or m.geom(other).name)
    return {("table" if n in ("", "world") else n) for n in out}


def _fingers(world: SimWorld) -> set[str]:
    m = world.model
    names = set(world.spec.gripper.finger_links) | {world.spec.gripper.parent}
    return {m.body(m.body_rootid[m.body(n).id]).name for n in names} | names


def task_truth(world: SimWorld, instr: Instruction) -> TaskTruthRecord | None:
    """The task's truth now, or None for the grammar's other actions."""
    with world.lock:
        mujoco.mj_forward(world.model, world.data)
        if instr.action == "sweep":
            return _sweep(world, instr)
        if instr.action in ("lift", "take_off"):
            return _lifted(world, instr)
        if instr.action == "stand_up":
            return _stood(world, instr)
    return None


def _stood(world: SimWorld, instr: Instruction) -> TaskTruthRecord:
    """Standing the right way up: its axis within UPRIGHT_TOL_DEG of vertical, a bottle's neck end up (a can, one
    radius all along, either end). The goal comparison alone is against the grounded motion, which a registration
    that turned a bottle end for end would have made a bottle standing on its neck."""
    found = named(world, instr.target)
    if len(found) != 1:
        return TaskTruthRecord(action=instr.action, done=False, detail=f"'{instr.target}' names {len(found)} objects")
    o = found[0]
    axis = world.data.geom(f"{o.name}_g0").xmat.reshape(3, 3)[:, 2]  # a bottle's: from its body to its neck
    up = float(axis[2]) if o.kind == "bottle" else abs(float(axis[2]))
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, up))))
    what = "neck end" if o.kind == "bottle" else "axis"
    return TaskTruthRecord(
        action=instr.action,
        done=tilt <= UPRIGHT_TOL_DEG,
        detail=f"{o.name}'s {what} {tilt:.0f} deg from straight up (at most {UPRIGHT_TOL_DEG:.0f})",
    )


def _sweep(world: SimWorld, instr: Instruction) -> TaskTruthRecord:
    parts = named(world, instr.target)
    containers = named(world, instr.reference)
    if not parts or len(containers) != 1:
        why = f"'{instr.target}' names {len(parts)} objects, '{instr.reference}' {len(containers)} (needs one)"
        return TaskTruthRecord(action="sweep", done=False, detail=why)
    c = containers[0]
    T = world.object_pose(c.name)
    dx, dy, wall = c.size_m
    inside = 0
    for o in parts:
        centre = world.data.geom_xpos[_geoms(world, o.name)].mean(axis=0)
        x, y, z = T[:3, :3].T @ (centre - T[:3, 3])
        inside += abs(x) <= dx / 2 - DUSTPAN_WALL_M and abs(y) <= dy / 2 - DUSTPAN_WALL_M and z < wall + o.height_m
    need = math.ceil(SWEPT_FRACTION * len(parts) - 1e-9)
    return TaskTruthRecord(
        action="sweep",
        done=inside >= need,
        detail=f"{inside} of {len(parts)} {instr.target} over the {instr.reference}'s floor (need {need})",
        parts_inside=int(inside),
        parts_total=len(parts),
    )


def _lifted(world: SimWorld, instr: Instruction) -> TaskTruthRecord:
    found = named(world, instr.target)
    if len(found) != 1:
        return TaskTruthRecord(action=instr.action, done=False, detail=f"'{instr.target}' names {len(found)} objects")
    name = found[0].name
    low = lowest_point(world, name)
    contacts = sorted(touching(world, name) - _fingers(world))
    if instr.action == "lift":
        done = not contacts and low >= CLEAR_M
        detail = f"lowest point {low * 1000:.0f} mm above the table, touching {contacts or 'only the fingers'}"
        return TaskTruthRecord(action="lift", done=done, detail=detail, lifted_m=low, touching=contacts)
    supports = named(world, instr.reference or "")
    on_support = [s.name for s in supports if s.name in contacts]
    done = not on_support and set(contacts) <= {"table"} and "table" in contacts and low < ON_TABLE_M
    detail = f"touching {contacts or 'nothing'}; lowest point {low * 1000:.0f} mm above the table" + (
        f"; still on {', '.join(on_support)}" if on_support else ""
    )
    return TaskTruthRecord(action="take_off", done=done, detail=detail, lifted_m=low, touching=contacts)
