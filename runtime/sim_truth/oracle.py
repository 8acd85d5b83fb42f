"""Contact decided from the simulator's ground truth: a top-down grasp across the target's side faces.

For tests and benchmarks of everything around the contact stage (grounding's motion applied to the grasp,
planning, the gate, execution, verification) while pipeline.contact is absent or under test. Never used by
`goalvla run`; it needs the SimWorld's object poses, which a real cell does not have. It hands over the same
ContactPlan pipeline.contact does, its joints solved by the safety IK (the manipulation checks them).
"""

from __future__ import annotations

import numpy as np

from drivers.sim.world import SimWorld
from motion.goals import lifted
from motion.manipulation.phases import place_heights
from pipeline.contact.clouds import SceneClouds
from pipeline.contact.types import ContactPlan
from runtime.run.context import RunContext, StageError
from runtime.run.stages import PipelineStages
from safety.geometry import Primitive
from safety.robot_model import RobotModel

PRE_GRASP_M = 0.12
FINGER_SQUEEZE_M = 0.02  # commanded gap below the object's width, so the fingers stop on it
GRASP_HEIGHT_M = 0.005  # the TCP this far above the object's middle


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


def box_size(world: SimWorld, name: str) -> tuple[float, float, float]:
    """Full extents of a scene object's bounding box (its body frame), from the scene description."""
    obj = next(o for o in world.scene.objects if o.name == name)
    if obj.kind == "box":
        return tuple(obj.size_m)
    if obj.kind == "cylinder":
        return (2 * obj.radius_m, 2 * obj.radius_m, obj.height_m)
    if obj.kind == "sphere":
        return (2 * obj.radius_m,) * 3
    raise StageError(f"the ground-truth grasp handles upright boxes, cylinders and spheres, not {obj.kind} ({name})")


def ground_truth_grasp(
    world: SimWorld, name: str, *, T_motion: np.ndarray, robot: RobotModel, q_start: np.ndarray, padding_m: float
) -> ContactPlan:
    """The top-down grasp of scene object `name`, carried by T_motion (base frame), with its joints; StageError
    naming the pose that has no IK solution."""
    size = box_size(world, name)
    T_contact = top_down_grasp(world.object_pose(name), size[2] / 2 + GRASP_HEIGHT_M)
    T_pre = lifted(T_contact, PRE_GRASP_M)
    T_goal = T_motion @ T_contact
    T_place = tuple(lifted(T_goal, h) for h in place_heights(padding_m))
    qs = []
    for T, what in ((T_pre, "pre-grasp"), (T_contact, "grasp"), (T_goal, "goal"), *((T, "place") for T in T_place)):
        result = robot.ik(T, qs[-1] if qs else q_start)
        if not result.success:
            raise StageError(
                f"the ground-truth {what} pose at {np.round(T[:3, 3], 3)} m has no IK solution "
                f"(position residual {result.position_error_m * 1000:.1f} mm)"
            )
        qs.append(result.q)
    q_pre, q_contact, q_goal, *q_place = qs
    width = min(size[:2]) - FINGER_SQUEEZE_M
    return ContactPlan(
        mode="grasp",
        T_pre=T_pre,
        T_contact=T_contact,
        T_goal=T_goal,
        T_motion=T_motion,
        width_m=width,
        open_width_m=robot.spec.gripper.max_width_m,
        release_width_m=robot.spec.gripper.max_width_m,
        object_width_m=min(size[:2]),
        q_pre=q_pre,
        q_contact=q_contact,
        q_goal=q_goal,
        T_place=T_place,
        q_place=tuple(q_place),
        held=Primitive(f"held:{name}", robot.tcp_frame, "box", size),
        source="sim oracle",
    )


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

    def contacts(
        self, ctx: RunContext, clouds: SceneClouds, robot: RobotModel, q_start: np.ndarray
    ) -> list[ContactPlan]:
        world = ctx.devices.world
        if world is None:
            raise StageError("the ground-truth grasp needs the simulator")
        padding = ctx.profile.safety.padding_m
        grasp = ground_truth_grasp(
            world, target_object(ctx), T_motion=ctx.motion.T_base, robot=robot, q_start=q_start, padding_m=padding
        )
        return [grasp]
