"""The robot's clearance from the scene along a planned trajectory, for the report: at each sampled configuration,
the smallest distance from any of the arm's and gripper's collision shapes (the description's, unpadded) to the
camera's scene points (the target excluded, as the gate sees it before contact) and to the table top.

An approximation for people, not a safety check (the gate's own checks are exact and padded): shapes are
represented by points along their axes (capsules, cylinders) or on their surface (boxes) with their radius, and
the scene by its voxelised points.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from drivers.description.spec import Box, Capsule, Cylinder, RobotSpec
from safety.robot_model import RobotModel

SAMPLES_PER_PHASE = 80  # configurations per phase at which clearance is computed
AXIS_STEP_M = 0.02  # spacing of the points along a capsule's or cylinder's axis
TABLE_Z_M = 0.0
SKIPPED_LINKS = ("link_base", "link1")  # they stand on the table: their distance to it says nothing


def link_points(spec: RobotSpec) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per link: points in the link frame (K, 3) and the radius around each (K,)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    shapes = {name: link.collision for name, link in spec.links.items() if name not in SKIPPED_LINKS}
    for finger in spec.gripper.finger_links:
        shapes[finger] = spec.gripper.finger_collision
    for name, collision in shapes.items():
        points, radii = [], []
        for shape in collision:
            if isinstance(shape, Capsule | Cylinder):
                if isinstance(shape, Capsule):
                    p0, p1 = np.asarray(shape.p0), np.asarray(shape.p1)
                else:
                    half = np.array([0.0, 0.0, shape.length / 2])
                    p0, p1 = np.asarray(shape.xyz) - half, np.asarray(shape.xyz) + half
                n = max(2, int(np.ceil(np.linalg.norm(p1 - p0) / AXIS_STEP_M)) + 1)
                pts = p0 + np.linspace(0, 1, n)[:, None] * (p1 - p0)
                points.append(pts)
                radii.append(np.full(n, shape.radius))
            elif isinstance(shape, Box):
                g = np.stack(np.meshgrid(*[np.linspace(-0.5, 0.5, 3)] * 3, indexing="ij"), -1).reshape(-1, 3)
                points.append(np.asarray(shape.xyz) + g * np.asarray(shape.size))
                radii.append(np.zeros(len(g)))
        if points:
            out[name] = (np.vstack(points), np.concatenate(radii))
    return out


def clearance_along(robot: RobotModel, positions: np.ndarray, dt: float, scene_points: np.ndarray | None) -> np.ndarray:
    """(M, 2): time [s] and clearance [m] at up to SAMPLES_PER_PHASE configurations spread over the trajectory."""
    shapes = link_points(robot.spec)
    tree = cKDTree(scene_points) if scene_points is not None and len(scene_points) else None
    index = np.unique(np.linspace(0, len(positions) - 1, min(len(positions), SAMPLES_PER_PHASE)).astype(int))
    out = np.empty((len(index), 2))
    for row, k in enumerate(index):
        poses = robot.fk(positions[k])
        best = np.inf
        for link, (points, radii) in shapes.items():
            T = poses[link]
            world = points @ T[:3, :3].T + T[:3, 3]
            best = min(best, float(np.min(world[:, 2] - TABLE_Z_M - radii)))
            if tree is not None:
                d, _ = tree.query(world)
                best = min(best, float(np.min(d - radii)))
        out[row] = (k * dt, best)
    return out
