"""Helpers for contact tests: clouds from the sim camera, and executing a plan with the sim arm and gripper."""

from __future__ import annotations

import numpy as np

from pipeline.contact.clouds import target_and_scene


def clouds(world, camera, robot, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(target points, scene points without the target, camera position), base frame, from one capture."""
    frame = camera.read().with_extrinsics(camera.T_base_camera)
    q = world.data.qpos[world.arm_qpos].copy()
    target, scene = target_and_scene(frame, camera.object_masks()[name], robot, q)
    return target, scene, frame.T_base_camera[:3, 3]


def move(world, arm, q_target: np.ndarray, seconds: float) -> None:
    """Stream a straight joint-space line to q_target at 100 Hz (stepped world)."""
    q0 = arm.read_state().q
    n = max(2, int(seconds * 100))
    for s in np.linspace(0, 1, n)[1:]:
        a = 0.5 - 0.5 * np.cos(np.pi * s)  # smooth start and stop
        arm.servo(q0 + a * (q_target - q0))
        world.step(0.01)


def execute_grasp(world, arm, gripper, plan) -> None:
    gripper.command(world.spec.gripper.max_width_m)
    move(world, arm, plan.q_pre, 2.0)
    move(world, arm, plan.q_contact, 1.5)
    gripper.command(plan.width_m)
    world.step(1.0)
    move(world, arm, plan.q_goal, 1.5)
    world.step(0.5)
