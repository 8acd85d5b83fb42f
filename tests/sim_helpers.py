"""Helpers for simulation tests: a small damped-least-squares IK on the MuJoCo model."""

from __future__ import annotations

import numpy as np

from drivers.sim.gl import mujoco
from drivers.sim.world import SimWorld


def top_down_grasp_pose(T_base_object: np.ndarray, height_m: float) -> np.ndarray:
    """TCP pose pointing down at the object's origin + height, fingers closing along the object's y axis."""
    y = T_base_object[:3, 1].copy()
    y[2] = 0.0
    y /= np.linalg.norm(y)
    z = np.array([0.0, 0.0, -1.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    T[:3, 3] = T_base_object[:3, 3] + [0.0, 0.0, height_m]
    return T


def ik(world: SimWorld, T_target: np.ndarray, q0: np.ndarray, iters: int = 300) -> np.ndarray:
    """DLS IK for the tcp site on a scratch copy of the world's data (test helper, not the safety IK)."""
    m = world.model
    d = mujoco.MjData(m)
    q = q0.astype(float).copy()
    site = m.site("tcp").id
    jp, jr = np.zeros((3, m.nv)), np.zeros((3, m.nv))
    for _ in range(iters):
        d.qpos[world.arm_qpos] = q
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        R = d.site_xmat[site].reshape(3, 3)
        e_p = T_target[:3, 3] - d.site_xpos[site]
        e_r = 0.5 * sum(np.cross(R[:, i], T_target[:3, i]) for i in range(3))
        err = np.concatenate([e_p, e_r])
        if np.linalg.norm(err) < 1e-6:
            return q
        mujoco.mj_jacSite(m, d, jp, jr, site)
        J = np.vstack([jp, jr])[:, world.arm_dof]
        q += J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(6), err)
        q = np.clip(q, world.spec.lower, world.spec.upper)
    raise AssertionError(f"test IK did not converge: residual {np.linalg.norm(err):.2e}")


def set_hinge(world: SimWorld, joint: str, angle_rad: float) -> None:
    """Put a hinge at an angle, kinematics only (no physics step)."""
    world.data.qpos[world.model.joint(joint).qposadr[0]] = angle_rad
    mujoco.mj_kinematics(world.model, world.data)


def body_pose(world: SimWorld, body: str) -> np.ndarray:
    """T_base_body of any body, including an object's part (world frame = base frame)."""
    b = world.model.body(body).id
    T = np.eye(4)
    T[:3, :3] = world.data.xmat[b].reshape(3, 3)
    T[:3, 3] = world.data.xpos[b]
    return T


def put_object(world: SimWorld, name: str, xyz_m: tuple[float, float, float], settle_s: float = 0.5) -> None:
    """Set a free object's centre down at xyz_m, upright as it stood, and let the physics settle it (an object
    put on another, where displace() only slides objects on the table)."""
    joint = world.model.joint(f"{name}_free")
    adr, dof = joint.qposadr[0], joint.dofadr[0]
    world.data.qpos[adr : adr + 3] = xyz_m
    world.data.qvel[dof : dof + 6] = 0.0
    mujoco.mj_forward(world.model, world.data)
    world.step(settle_s)


def write_scene(path, objects: list[dict]) -> str:
    """A scene file of these objects placed exactly as given (no jitter), named by the file; its path, for the
    profile's sim.scene."""
    import yaml

    scene = {"name": path.stem, "objects": objects, "randomise": {"xy_jitter_m": 0.0, "yaw_jitter_deg": 0.0}}
    path.write_text(yaml.safe_dump(scene))
    return str(path)


def write_can_and_scale(path) -> str:
    """A scene file: a white can beside a light red scale, whose weighing plate is white too (the can set on it is
    one white region with the plate); its path, for the profile's sim.scene."""
    import yaml

    objects = [
        {
            "name": "can",
            "kind": "cylinder",
            "color": "white",
            "radius_m": 0.031,
            "height_m": 0.059,
            "xy_m": [0.42, -0.30],
        },
        {"name": "scale", "kind": "platform", "color": "light_red", "size_m": [0.101, 0.112, 0.031]}
        | {"xy_m": [0.41, -0.01], "yaw_deg": -142.0},
    ]
    path.write_text(yaml.safe_dump({"name": "s", "objects": objects, "randomise": {"xy_jitter_m": 0.0}}))
    return str(path)
