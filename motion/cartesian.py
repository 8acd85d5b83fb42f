"""Straight-line TCP motions (approach and retreat along the gripper axis) as joint-space waypoints.

The line is cut into steps of at most step_m / step_rad; each step is solved by IK seeded with the previous
solution, and must move no joint more than max_jump_rad (a larger change means a flip or a singularity, where
the joint motion between two close poses is not the straight line the operator expects) and must be
collision-free along the way. The dense solution is then thinned to the fewest waypoints whose straight
joint-space segments keep the TCP within tolerance_m of the line, each thinned segment re-checked for collision.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from motion.planner import Planner
from safety.ik import IKSettings


class CartesianPathError(RuntimeError):
    """The straight line cannot be followed: IK failure, a configuration jump or a collision, with where."""


def interpolate_poses(T_from: np.ndarray, T_to: np.ndarray, n: int) -> list[np.ndarray]:
    """n + 1 poses from T_from to T_to: positions on the segment, orientations by slerp."""
    slerp = Slerp([0.0, 1.0], Rotation.from_matrix([T_from[:3, :3], T_to[:3, :3]]))
    s = np.linspace(0.0, 1.0, n + 1)
    R = slerp(s).as_matrix()
    out = []
    for k in range(n + 1):
        T = np.eye(4)
        T[:3, :3] = R[k]
        T[:3, 3] = (1 - s[k]) * T_from[:3, 3] + s[k] * T_to[:3, 3]
        out.append(T)
    return out


def cartesian_path(
    planner: Planner,
    q_start: np.ndarray,
    T_base_target: np.ndarray,
    step_m: float = 0.005,
    step_rad: float = 0.05,
    max_jump_rad: float = 0.15,
    tolerance_m: float = 0.002,
) -> np.ndarray:
    """Joint waypoints (M, dof) moving the TCP on the straight line from its pose at q_start to T_base_target."""
    robot, limits = planner.world.robot, planner.limits
    q_start = np.asarray(q_start, dtype=np.float64)
    T0 = robot.tcp_pose(q_start)
    distance = float(np.linalg.norm(T_base_target[:3, 3] - T0[:3, 3]))
    angle = float(Rotation.from_matrix(T0[:3, :3].T @ T_base_target[:3, :3]).magnitude())
    n = max(1, int(np.ceil(max(distance / step_m, angle / step_rad))))
    poses = interpolate_poses(T0, T_base_target, n)
    settings = IKSettings(restarts=0, margin_rad=float(np.max(limits.lower - robot.lower)))
    dense = [q_start]
    for k, T in enumerate(poses[1:], start=1):
        result = robot.ik(T, dense[-1], preferred_q=dense[-1], settings=settings)
        where = f"{k}/{n} of the way, TCP at {np.round(T[:3, 3], 3)} m"
        if not result.success:
            raise CartesianPathError(f"IK failed {where}: {result.reason}")
        jump = np.abs(result.q - dense[-1])
        if jump.max() > max_jump_rad:
            j = int(np.argmax(jump))
            raise CartesianPathError(
                f"joint {j + 1} jumps {jump[j]:.3f} rad > {max_jump_rad} rad {where} (flip or singularity)"
            )
        if not planner.segment_free(dense[-1], result.q):
            raise CartesianPathError(f"collision {where}: {planner.why_invalid(result.q, 'the')}")
        dense.append(result.q)
    return _thin(planner, np.array(dense), poses, tolerance_m)


def _thin(planner: Planner, dense: np.ndarray, poses: list[np.ndarray], tolerance_m: float) -> np.ndarray:
    """Greedily keep the fewest waypoints whose joint-space segments stay within tolerance of the TCP line."""
    robot = planner.world.robot
    line = np.array([T[:3, 3] for T in poses])
    keep = [0]
    while keep[-1] < len(dense) - 1:
        i = keep[-1]
        j = i + 1
        while j + 1 < len(dense) and _follows(robot, dense, line, i, j + 1, tolerance_m, planner):
            j += 1
        keep.append(j)
    return dense[keep]


def _follows(robot, dense: np.ndarray, line: np.ndarray, i: int, j: int, tolerance_m: float, planner: Planner) -> bool:
    s = (np.arange(i + 1, j) - i) / (j - i)
    q = dense[i] + s[:, None] * (dense[j] - dense[i])
    if len(q) and np.max(np.linalg.norm(robot.tcp_positions(q) - line[i + 1 : j], axis=1)) > tolerance_m:
        return False
    return planner.segment_free(dense[i], dense[j])
