"""Helpers for contact tests: clouds from the sim camera, and executing a plan with the sim arm and gripper."""

from __future__ import annotations

import numpy as np

from pipeline.contact.clouds import scene_clouds


def clouds(world, camera, robot, name: str, body: str | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(target points, scene points without the target or the hand, camera position), base frame, from one capture
    (the run's own cloud builder, at 5 mm voxels).

    The target is the scene object `name`, or only its part `body` (a MuJoCo body, e.g. a lid) when given.
    """
    frame = camera.read().with_extrinsics(camera.T_base_camera)
    q = world.data.qpos[world.arm_qpos].copy()
    mask = camera.object_masks()[name] if body is None else camera.body_mask(body)
    built = scene_clouds(frame, mask, robot, q, voxel_m=0.005)
    return built.target, built.scene, frame.T_base_camera[:3, 3]


def hinge_angle(world, joint: str) -> float:
    """A hinge joint's angle now [rad]."""
    return float(world.data.qpos[world.model.joint(joint).qposadr[0]])


def body_motion(world, body: str, joint: str, angle_rad: float) -> np.ndarray:
    """x_goal = T x_now (base frame) of a body when its hinge joint turns to angle_rad, everything else kept."""
    import mujoco  # here, not at the top: drivers.sim picks the GL backend before mujoco is first imported

    m, data = world.model, mujoco.MjData(world.model)
    data.qpos[:] = world.data.qpos
    poses = []
    for angle in (hinge_angle(world, joint), angle_rad):
        data.qpos[m.joint(joint).qposadr[0]] = angle
        mujoco.mj_kinematics(m, data)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = data.body(body).xmat.reshape(3, 3), data.body(body).xpos
        poses.append(T)
    return poses[1] @ np.linalg.inv(poses[0])


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
