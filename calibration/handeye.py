"""Hand-eye solve: OpenCV's five AX = XB methods, each scored by how consistently it explains every view, then
the best one refined by minimising the board corners' reprojection error over all views (X and the board's pose
together), and the result scored the same way.

Modes and unknowns (A_i = T_base_flange of view i, B_i = T_camera_board measured by PnP):
- eye_to_hand: X = T_base_camera, Y = T_flange_board (board carried by the arm); B_i = X^-1 A_i Y.
- eye_in_hand: X = T_flange_camera, Y = T_base_board (board on the table);     B_i = X^-1 A_i^-1 Y.
A view's residual compares the board pose predicted from (X, Y) and the robot with the one the camera measured:
distance between the predicted and measured board centre [mm] and the rotation between them [deg].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from calibration.detect import BoardObservation

Mode = Literal["eye_to_hand", "eye_in_hand"]
METHODS = {
    "tsai": cv2.CALIB_HAND_EYE_TSAI,
    "park": cv2.CALIB_HAND_EYE_PARK,
    "horaud": cv2.CALIB_HAND_EYE_HORAUD,
    "andreff": cv2.CALIB_HAND_EYE_ANDREFF,
    "daniilidis": cv2.CALIB_HAND_EYE_DANIILIDIS,
}
MM_PER_DEG = 10.0  # weight of rotation against translation when ranking solutions


class HandEyeError(RuntimeError):
    pass


@dataclass(frozen=True)
class Candidate:
    method: str
    X: np.ndarray  # T_base_camera or T_flange_camera
    Y: np.ndarray  # T_flange_board or T_base_board
    residual_mm: np.ndarray  # per view
    residual_deg: np.ndarray  # per view

    @property
    def score(self) -> float:
        return float(np.median(self.residual_mm) + MM_PER_DEG * np.median(self.residual_deg))


@dataclass(frozen=True)
class HandEyeResult:
    mode: Mode
    best: Candidate
    candidates: list[Candidate] = field(default_factory=list)

    @property
    def median_mm(self) -> float:
        return float(np.median(self.best.residual_mm))

    @property
    def median_deg(self) -> float:
        return float(np.median(self.best.residual_deg))


def _pose(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, np.ravel(t)
    return T


def _chain(mode: Mode, T_base_flange: np.ndarray) -> np.ndarray:
    """C_i with B_i = X^-1 C_i Y."""
    return T_base_flange if mode == "eye_to_hand" else np.linalg.inv(T_base_flange)


def _mean_pose(poses: list[np.ndarray]) -> np.ndarray:
    R = Rotation.from_matrix(np.array([T[:3, :3] for T in poses])).mean().as_matrix()
    return _pose(R, np.mean([T[:3, 3] for T in poses], axis=0))


def evaluate(
    mode: Mode,
    method: str,
    X: np.ndarray,
    A: list[np.ndarray],
    B: list[np.ndarray],
    centre: np.ndarray,
    Y: np.ndarray | None = None,
) -> Candidate:
    """Score X (and Y; estimated from X when not given) against every view."""
    C = [_chain(mode, a) for a in A]
    if Y is None:
        Y = _mean_pose([np.linalg.inv(c) @ X @ b for c, b in zip(C, B, strict=True)])
    X_inv = np.linalg.inv(X)
    mm, deg = [], []
    for c, b in zip(C, B, strict=True):
        predicted = X_inv @ c @ Y
        mm.append(
            1000.0 * np.linalg.norm(predicted[:3, :3] @ centre + predicted[:3, 3] - b[:3, :3] @ centre - b[:3, 3])
        )
        deg.append(np.degrees(Rotation.from_matrix(b[:3, :3].T @ predicted[:3, :3]).magnitude()))
    return Candidate(method, X, Y, np.array(mm), np.array(deg))


def opencv_candidates(mode: Mode, A: list[np.ndarray], B: list[np.ndarray], centre: np.ndarray) -> list[Candidate]:
    """Every OpenCV method's X, scored. For eye-to-hand OpenCV is given base->flange instead of flange->base."""
    G = [np.linalg.inv(a) if mode == "eye_to_hand" else a for a in A]
    out = []
    for name, flag in METHODS.items():
        R, t = cv2.calibrateHandEye(
            [g[:3, :3] for g in G], [g[:3, 3] for g in G], [b[:3, :3] for b in B], [b[:3, 3] for b in B], method=flag
        )
        X = _pose(R, t)
        if np.all(np.isfinite(X)) and abs(np.linalg.det(X[:3, :3]) - 1.0) < 1e-6:
            out.append(evaluate(mode, name, X, A, B, centre))
    return out


def refine(
    mode: Mode, start: Candidate, A: list[np.ndarray], views: list[BoardObservation], K: np.ndarray, centre: np.ndarray
) -> Candidate:
    """Minimise the reprojection error of every detected corner over X and Y (12 parameters, robust loss)."""
    C = [_chain(mode, a) for a in A]

    def unpack(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (
            _pose(Rotation.from_rotvec(p[0:3]).as_matrix(), p[3:6]),
            _pose(Rotation.from_rotvec(p[6:9]).as_matrix(), p[9:12]),
        )

    def residuals(p: np.ndarray) -> np.ndarray:
        X, Y = unpack(p)
        X_inv = np.linalg.inv(X)
        out = []
        for c, v in zip(C, views, strict=True):
            T = X_inv @ c @ Y
            cam = v.object_points @ T[:3, :3].T + T[:3, 3]
            uv = cam[:, :2] / cam[:, 2:3] * [K[0, 0], K[1, 1]] + [K[0, 2], K[1, 2]]
            out.append((uv - v.image_points).ravel())
        return np.concatenate(out)

    p0 = np.concatenate(
        [
            Rotation.from_matrix(start.X[:3, :3]).as_rotvec(),
            start.X[:3, 3],
            Rotation.from_matrix(start.Y[:3, :3]).as_rotvec(),
            start.Y[:3, 3],
        ]
    )
    fit = least_squares(residuals, p0, loss="huber", f_scale=1.0, x_scale="jac")
    X, Y = unpack(fit.x)
    return evaluate(mode, f"{start.method}+reprojection", X, A, [v.T_camera_board for v in views], centre, Y)


def rotation_diversity_deg(A: list[np.ndarray]) -> float:
    """How well the views' relative rotations span two non-parallel axes: the second-largest singular value of
    their rotation vectors [deg]; AX = XB needs it well above zero."""
    rv = np.array([Rotation.from_matrix(A[0][:3, :3].T @ a[:3, :3]).as_rotvec() for a in A[1:]])
    return float(np.degrees(np.linalg.svd(rv, compute_uv=False)[1] / np.sqrt(len(rv)))) if len(rv) > 1 else 0.0


def solve_hand_eye(
    mode: Mode, T_base_flange: list[np.ndarray], views: list[BoardObservation], K: np.ndarray, board_centre: np.ndarray
) -> HandEyeResult:
    """Best consistent hand-eye result over OpenCV's methods and the reprojection refinement of the best one."""
    if len(views) != len(T_base_flange):
        raise ValueError(f"{len(T_base_flange)} robot poses for {len(views)} board views")
    if len(views) < 3:
        raise HandEyeError(f"hand-eye needs at least 3 views with the board, got {len(views)}")
    B = [v.T_camera_board for v in views]
    candidates = opencv_candidates(mode, T_base_flange, B, board_centre)
    if not candidates:
        raise HandEyeError("no OpenCV hand-eye method gave a valid rotation (degenerate poses?)")
    first = min(candidates, key=lambda c: c.score)
    candidates.append(refine(mode, first, T_base_flange, views, K, board_centre))
    return HandEyeResult(mode, min(candidates, key=lambda c: c.score), candidates)
