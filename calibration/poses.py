"""A diverse hand-eye pose set: flange poses that show the board to the camera from many directions.

eye_to_hand: the board rides on the flange; its centre visits points around `target_centre_m` with its printed
face turned toward the (roughly known) camera, tilted up to `tilt_deg` about random axes and rolled in-plane.
eye_in_hand: the board lies at `target_centre_m`; the camera on the flange looks at its centre from a cap of
directions at `standoff_m`. Each pose must have an IK solution inside the joint limits (margin kept); the gate
checks the motions between them before anything moves. Seeded, so the same profile gives the same poses.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from calibration.board import CharucoBoardSpec


@dataclass(frozen=True)
class PosePlan:
    T_base_flange: list[np.ndarray]
    q: list[np.ndarray]
    rejected: int  # candidates without an acceptable IK solution


UP = np.array([0.0, 0.0, 1.0])


def look_rotation(forward: np.ndarray, up_hint: np.ndarray = UP) -> np.ndarray:
    """Rotation whose z axis is `forward` and whose y axis points away from up_hint (camera convention)."""
    z = forward / np.linalg.norm(forward)
    x = np.cross(z, up_hint)
    if np.linalg.norm(x) < 1e-6:
        x = np.cross(z, [1.0, 0.0, 0.0])
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def board_centre(board: CharucoBoardSpec) -> np.ndarray:
    w, h = board.size_m
    return np.array([w / 2, h / 2, 0.0])


def eye_to_hand_targets(
    board: CharucoBoardSpec,
    T_flange_board: np.ndarray,
    camera_position: np.ndarray,
    centre: np.ndarray,
    spread_m: float,
    tilt_deg: float,
    n: int,
    rng: np.random.Generator,
) -> list[np.ndarray]:
    """T_base_flange candidates that put the board's printed face (board -z) toward the camera."""
    out = []
    for _ in range(n):
        c = centre + rng.uniform(-spread_m, spread_m, 3) * [1.0, 1.0, 0.6]
        R_face = look_rotation(camera_position - c)  # z toward the camera = printed-face normal
        tilt = Rotation.from_rotvec(_random_tilt(rng, tilt_deg)).as_matrix()
        roll = Rotation.from_euler("z", rng.uniform(-45, 45), degrees=True).as_matrix()
        R_board = R_face @ tilt @ roll @ np.diag([1.0, -1.0, -1.0])  # board z points away from the camera
        T_base_board = _pose(R_board, c - R_board @ board_centre(board))
        out.append(T_base_board @ np.linalg.inv(T_flange_board))
    return out


def eye_in_hand_targets(
    board: CharucoBoardSpec,
    T_base_board: np.ndarray,
    T_flange_camera: np.ndarray,
    standoff_m: float,
    tilt_deg: float,
    n: int,
    rng: np.random.Generator,
) -> list[np.ndarray]:
    """T_base_flange candidates with the flange camera looking at the board centre from above at ~standoff."""
    centre = T_base_board[:3, :3] @ board_centre(board) + T_base_board[:3, 3]
    out = []
    for _ in range(n):
        azimuth = rng.uniform(-np.pi, np.pi)
        polar = np.radians(rng.uniform(0.0, tilt_deg))
        direction = np.array([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
        position = centre + direction * standoff_m * rng.uniform(0.85, 1.15)
        R_cam = look_rotation(centre - position, up_hint=np.array([1.0, 0.0, 0.0]))
        R_cam = R_cam @ Rotation.from_euler("z", rng.uniform(-60, 60), degrees=True).as_matrix()
        out.append(_pose(R_cam, position) @ np.linalg.inv(T_flange_camera))
    return out


def _random_tilt(rng: np.random.Generator, max_deg: float) -> np.ndarray:
    axis = np.array([*rng.normal(size=2), 0.0])
    axis /= np.linalg.norm(axis)
    return axis * np.radians(rng.uniform(0.3, 1.0) * max_deg)


def solve_poses(
    targets: list[np.ndarray],
    ik: Callable[[np.ndarray, np.ndarray], np.ndarray | None],
    q_start: np.ndarray,
    wanted: int,
) -> PosePlan:
    """IK for each target (seeded from the previous solution), keeping the first `wanted` that solve, then
    ordered greedily by joint distance so the arm travels little between views."""
    solved: list[tuple[np.ndarray, np.ndarray]] = []
    rejected = 0
    seed = q_start
    for T in targets:
        if len(solved) == wanted:
            break
        q = ik(T, seed)
        if q is None:
            rejected += 1
            continue
        solved.append((T, q))
        seed = q
    order, current, left = [], q_start, list(range(len(solved)))
    while left:
        k = min(left, key=lambda i: float(np.max(np.abs(solved[i][1] - current))))
        order.append(k)
        left.remove(k)
        current = solved[k][1]
    return PosePlan([solved[k][0] for k in order], [solved[k][1] for k in order], rejected)
