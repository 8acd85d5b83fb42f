"""Inverse kinematics by damped least squares on Pinocchio, with joint limits, a preferred posture in the null
space and random restarts.

Each attempt iterates q <- clip(q + dq) with dq = J^T (J J^T + lambda^2 I)^-1 e + N (q_pref - q) k, where e is
the SE(3) log error of the target seen from the current frame and J the matching log-Jacobian. The damping
grows with the error (robust far away) and vanishes near the solution (exact convergence); the step is capped
so a near-singular J cannot throw the arm around. Continuous joints (+-2 pi) are finally wrapped to the copy
nearest the seed, so motion planners get the shortest way there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from safety.config import SafetyConfig

if TYPE_CHECKING:
    from safety.robot_model import RobotModel


@dataclass(frozen=True)
class IKSettings:
    position_tolerance_m: float = 1e-5
    rotation_tolerance_rad: float = 1e-4
    max_iterations: int = 80
    restarts: int = 30  # random seeds after q_seed and the preferred posture
    margin_rad: float = SafetyConfig().joint_margin_rad  # kept from every joint limit
    max_step_rad: float = 0.4  # largest joint change per iteration
    posture_gain: float = 0.05  # null-space pull toward the preferred posture
    seed: int = 0  # random restarts are reproducible


@dataclass(frozen=True)
class IKResult:
    """Outcome of one IK query. On failure q is the best configuration found and the errors its residual."""

    success: bool
    q: np.ndarray
    position_error_m: float
    rotation_error_rad: float
    iterations: int  # summed over attempts
    attempts: int
    reason: str = ""


def _pose_error(data: pin.Data, fid: int, target: pin.SE3) -> tuple[np.ndarray, pin.SE3]:
    current_M_target = data.oMf[fid].actInv(target)
    return pin.log6(current_M_target).vector, current_M_target


def _wrap_near(q: np.ndarray, ref: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """Shift each angle by a multiple of 2 pi toward ref, as long as it stays within the limits."""
    k = np.round((ref - q) / (2 * np.pi))
    shifted = q + 2 * np.pi * k
    ok = (shifted >= lower) & (shifted <= upper)
    return np.where(ok, shifted, q)


def _attempt(robot: RobotModel, fid: int, target: pin.SE3, q0: np.ndarray, q_pref: np.ndarray, lo, hi, s):
    model, data, n = robot.model, robot.data, robot.dof
    qf = robot.full_q(q0)
    eye6 = np.eye(6)
    best = (np.inf, qf[:n].copy(), np.inf, np.inf)
    for it in range(1, s.max_iterations + 1):
        pin.computeJointJacobians(model, data, qf)  # forward kinematics + joint Jacobians in one pass
        pin.updateFramePlacement(model, data, fid)
        err, cMt = _pose_error(data, fid, target)
        pos_err = float(np.linalg.norm(data.oMf[fid].translation - target.translation))
        rot_err = float(np.linalg.norm(err[3:]))
        score = pos_err + 0.1 * rot_err
        if score < best[0]:
            best = (score, qf[:n].copy(), pos_err, rot_err)
        if pos_err < s.position_tolerance_m and rot_err < s.rotation_tolerance_rad:
            return True, best[1], pos_err, rot_err, it
        J = pin.Jlog6(cMt.inverse()) @ pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL)[:, :n]
        lam2 = 1e-8 + 1e-3 * min(1.0, float(err @ err))
        posture = s.posture_gain * (q_pref - qf[:n])
        # dq = J+ err + (I - J+ J) posture with J+ = J^T (J J^T + lam2 I)^-1: one solve for both right-hand sides
        y = np.linalg.solve(J @ J.T + lam2 * eye6, np.column_stack([err, J @ posture]))
        dq = J.T @ (y[:, 0] - y[:, 1]) + posture
        peak = np.max(np.abs(dq))
        if peak > s.max_step_rad:
            dq *= s.max_step_rad / peak
        qf[:n] = np.minimum(np.maximum(qf[:n] + dq, lo), hi)
    return False, best[1], best[2], best[3], s.max_iterations


def solve_ik(
    robot: RobotModel,
    T_base_target: np.ndarray,
    fid: int,
    *,
    q_seed: np.ndarray | None,
    preferred_q: np.ndarray,
    settings: IKSettings,
    accept: Callable[[np.ndarray], bool] | None,
    rng: np.random.Generator | None,
) -> IKResult:
    """See RobotModel.ik."""
    if T_base_target.shape != (4, 4) or not np.all(np.isfinite(T_base_target)):
        raise ValueError(f"target must be a finite 4x4 pose, got shape {T_base_target.shape}")
    target = pin.SE3(T_base_target[:3, :3], T_base_target[:3, 3])
    lo, hi = robot.lower + settings.margin_rad, robot.upper - settings.margin_rad
    rng = rng or np.random.default_rng(settings.seed)
    seeds = [np.clip(np.asarray(s, dtype=np.float64), lo, hi) for s in (q_seed, preferred_q) if s is not None]
    seeds += [rng.uniform(lo, hi) for _ in range(settings.restarts)]
    ref = seeds[0]
    best: tuple[float, np.ndarray, float, float] = (np.inf, ref, np.inf, np.inf)
    total_iterations, rejected = 0, 0
    for attempt, q0 in enumerate(seeds, start=1):
        ok, q, pos_err, rot_err, iters = _attempt(robot, fid, target, q0, preferred_q, lo, hi, settings)
        total_iterations += iters
        if ok:
            q = _wrap_near(q, ref, lo, hi)
            if accept is None or accept(q):
                return IKResult(True, q, pos_err, rot_err, total_iterations, attempt)
            rejected += 1
        elif pos_err + 0.1 * rot_err < best[0]:
            best = (pos_err + 0.1 * rot_err, q, pos_err, rot_err)
    reason = f"no solution within {len(seeds)} attempts"
    if rejected:
        reason += f" ({rejected} kinematic solutions rejected by the acceptance check)"
    if np.isfinite(best[0]):
        reason += f"; best residual {best[2] * 1000:.2f} mm / {np.degrees(best[3]):.2f} deg"
    return IKResult(False, best[1], best[2], best[3], total_iterations, len(seeds), reason)
