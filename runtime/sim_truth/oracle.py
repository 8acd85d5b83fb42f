"""Contact decided from the simulator's ground truth: a top-down grasp across the target's side faces.

For tests and benchmarks of everything around the contact stage (grounding's motion applied to the grasp,
planning, the gate, execution, verification) while pipeline.contact is absent or under test. Never used by
`goalvla run`; it needs the SimWorld's object poses, which a real cell does not have.
"""

from __future__ import annotations

import numpy as np

from drivers.description import load_robot_spec
from motion.manipulation.phases import ContactPoses
from runtime.run.context import RunContext, StageError
from runtime.run.stages import PipelineStages
from safety.geometry import Primitive

PRE_GRASP_M = 0.12
FINGER_SQUEEZE_M = 0.02  # commanded gap below the object's width, so the fingers stop on it


def top_down_grasp(T_base_object: np.ndarray, height_m: float) -> np.ndarray:
    """TCP pose pointing down at the object's axis, fingers closing across one of its side-face pairs: of the
    four equivalent choices, the one turning the wrist least from the home posture (TCP x along base x)."""
    z = np.array([0.0, 0.0, -1.0])
    best = None
    for k in range(4):
        angle = k * np.pi / 2
        y = np.cos(angle) * T_base_object[:3, 0] + np.sin(angle) * T_base_object[:3, 1]
        y = y - (y @ z) * z
        y /= np.linalg.norm(y)
        x = np.cross(y, z)
        if best is None or x[0] > best[0][0]:
            best = (x, y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([best[0], best[1], z])
    T[:3, 3] = T_base_object[:3, 3] + [0.0, 0.0, height_m]
    return T


def box_size(world, name: str) -> tuple[float, float, float]:
    """Full extents of a scene object's bounding box (its body frame), from the scene description."""
    obj = next(o for o in world.scene.objects if o.name == name)
    if obj.kind == "box":
        return tuple(obj.size_m)
    if obj.kind == "cylinder":
        return (2 * obj.radius_m, 2 * obj.radius_m, obj.height_m)
    if obj.kind == "sphere":
        return (2 * obj.radius_m,) * 3
    raise StageError(f"the ground-truth grasp handles upright boxes, cylinders and spheres, not {obj.kind} ({name})")


def target_object(ctx: RunContext) -> str:
    """The scene object under the reasoning stage's initial mask (the sim camera's own segmentation)."""
    masks = ctx.devices.camera.object_masks()
    overlap = {name: int((m & ctx.goal.mask_init).sum()) for name, m in masks.items()}
    name = max(overlap, key=overlap.get)
    if overlap[name] == 0:
        raise StageError("the target mask covers no scene object")
    return name


class GroundTruthGraspStages(PipelineStages):
    """PipelineStages whose contact decision is the ground-truth top-down grasp of the target."""

    def contact_candidates(self, ctx: RunContext, chain) -> list[ContactPoses]:
        world = ctx.devices.world
        if world is None:
            raise StageError("the ground-truth grasp needs the simulator")
        name = target_object(ctx)
        size = box_size(world, name)
        T_contact = top_down_grasp(world.object_pose(name), size[2] / 2 + 0.005)
        T_pre = T_contact.copy()
        T_pre[2, 3] += PRE_GRASP_M
        held = Primitive(f"held:{name}", load_robot_spec().tcp_link, "box", size)
        width = min(size[:2]) - FINGER_SQUEEZE_M
        T_goal = ctx.motion.T_base @ T_contact
        return [ContactPoses("grasp", T_pre, T_contact, T_goal, width, held, source="sim oracle")]
