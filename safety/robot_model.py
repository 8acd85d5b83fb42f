"""Kinematics of the xArm 7 + gripper on Pinocchio, built from the project's own description.

The model is `pin.buildModelFromXML(build_urdf(load_robot_spec()))`: 7 revolute arm joints followed by the two
prismatic finger joints (each = half the finger gap; the right one mimics the left, so both are set from the
gripper width). Public methods take the 7 arm angles; the gripper width is a separate argument (default: open).

One RobotModel owns one `pin.Data` workspace, so it is not thread-safe: give each thread its own `copy()`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from drivers.description.spec import RobotSpec, load_robot_spec
from drivers.description.urdf import build_urdf
from safety.ik import IKResult, IKSettings, solve_ik

WORLD_ALIGNED = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class RobotModel:
    """Forward kinematics, Jacobians, IK and dexterity measures of the arm (base frame, SI units)."""

    def __init__(self, spec: RobotSpec | None = None) -> None:
        self.spec = spec or load_robot_spec()
        self.model = pin.buildModelFromXML(build_urdf(self.spec))
        self.data = self.model.createData()
        self.joint_names: tuple[str, ...] = self.spec.joint_names
        self.dof = len(self.joint_names)
        self.lower = self.spec.lower.copy()
        self.upper = self.spec.upper.copy()
        self.velocity_limits = self.spec.velocity_limits.copy()
        self.home_q = np.array(self.spec.home_q, dtype=np.float64)
        self.tcp_frame = self.spec.tcp_link
        self.link_names: tuple[str, ...] = (*self.spec.links, *self.spec.gripper.finger_links)
        self._frame_ids = {name: self.model.getFrameId(name) for name in self.link_names}
        self.tcp_frame_id = self._frame_ids[self.tcp_frame]
        self.finger_q_indices = [
            self.model.joints[self.model.getJointId(n)].idx_q for n in self.spec.gripper.finger_joints
        ]
        self._q = pin.neutral(self.model)
        self._default_half_gap = self.spec.gripper.max_width_m / 2

    def copy(self) -> RobotModel:
        """An independent model (own pin.Data) for another thread."""
        return RobotModel(self.spec)

    # ---- configuration -------------------------------------------------------------------------------------
    @property
    def gripper_width_m(self) -> float:
        """Finger gap [m] used when a call gives none (default: fully open)."""
        return 2 * self._default_half_gap

    def set_gripper_width(self, width_m: float) -> None:
        """Set the default finger gap [m]; clamped to the gripper's stroke."""
        self._default_half_gap = self._half_gap(width_m)

    def _half_gap(self, width_m: float) -> float:
        g = self.spec.gripper
        return float(np.clip(width_m, g.min_width_m, g.max_width_m)) / 2

    def full_q(self, q: np.ndarray, gripper_width_m: float | None = None) -> np.ndarray:
        """The Pinocchio configuration (arm angles + both finger joints) for arm angles q; gripper_width_m applies
        to this call only (default: gripper_width_m property)."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.dof,):
            raise ValueError(f"expected {self.dof} joint angles, got shape {q.shape}")
        self._q[: self.dof] = q
        half = self._default_half_gap if gripper_width_m is None else self._half_gap(gripper_width_m)
        self._q[self.finger_q_indices] = half
        return self._q.copy()

    def within_limits(self, q: np.ndarray, margin_rad: float = 0.0) -> bool:
        q = np.asarray(q)
        return bool(np.all(q >= self.lower + margin_rad) and np.all(q <= self.upper - margin_rad))

    # ---- forward kinematics ------------------------------------------------------------------------------------
    def _forward(self, q: np.ndarray, gripper_width_m: float | None) -> None:
        pin.framesForwardKinematics(self.model, self.data, self.full_q(q, gripper_width_m))

    def fk(self, q: np.ndarray, gripper_width_m: float | None = None) -> dict[str, np.ndarray]:
        """T_base_<link> (4x4) of every link, the fingers and the TCP frame `link_tcp`."""
        self._forward(q, gripper_width_m)
        return {name: self.data.oMf[fid].homogeneous.copy() for name, fid in self._frame_ids.items()}

    def frame_pose(self, q: np.ndarray, frame: str, gripper_width_m: float | None = None) -> np.ndarray:
        """T_base_<frame> for one named link or frame."""
        fid = self._frame_id(frame)
        pin.forwardKinematics(self.model, self.data, self.full_q(q, gripper_width_m))
        return pin.updateFramePlacement(self.model, self.data, fid).homogeneous.copy()

    def tcp_pose(self, q: np.ndarray) -> np.ndarray:
        """T_base_tcp: the gripper centre between the fingertips."""
        return self.frame_pose(q, self.tcp_frame)

    def tcp_positions(self, Q: np.ndarray) -> np.ndarray:
        """TCP positions (N, 3) for a batch of configurations (N, 7)."""
        out = np.empty((len(Q), 3))
        for k, q in enumerate(np.asarray(Q, dtype=np.float64)):
            self._q[: self.dof] = q
            pin.forwardKinematics(self.model, self.data, self._q)
            out[k] = pin.updateFramePlacement(self.model, self.data, self.tcp_frame_id).translation
        return out

    def _frame_id(self, frame: str) -> int:
        if not self.model.existFrame(frame):
            raise KeyError(f"unknown frame {frame!r}; links: {', '.join(self.link_names)}")
        return self.model.getFrameId(frame)

    # ---- differential kinematics -------------------------------------------------------------------------------
    def jacobian(self, q: np.ndarray, frame: str | None = None, world_aligned: bool = True) -> np.ndarray:
        """6x7 frame Jacobian [linear; angular] of the arm joints. world_aligned: velocities of the frame origin
        expressed in base axes (what a Cartesian speed limit needs); otherwise in the frame's own axes."""
        fid = self._frame_id(frame or self.tcp_frame)
        ref = WORLD_ALIGNED if world_aligned else pin.ReferenceFrame.LOCAL
        J = pin.computeFrameJacobian(self.model, self.data, self.full_q(q), fid, ref)
        return J[:, : self.dof].copy()

    def manipulability(self, q: np.ndarray) -> float:
        """Yoshikawa's measure sqrt(det(J J^T)) of the TCP Jacobian: 0 at a singularity."""
        s = np.linalg.svd(self.jacobian(q), compute_uv=False)
        return float(np.prod(s))

    def condition_number(self, q: np.ndarray) -> float:
        """Ratio of largest to smallest singular value of the TCP Jacobian (inf at a singularity). Linear and
        angular rows mix metres and radians, so compare values for the same robot only."""
        s = np.linalg.svd(self.jacobian(q), compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 1e-12 else float("inf")

    # ---- inverse kinematics ------------------------------------------------------------------------------------
    def ik(
        self,
        T_base_tcp: np.ndarray,
        q_seed: np.ndarray | None = None,
        *,
        preferred_q: np.ndarray | None = None,
        settings: IKSettings | None = None,
        accept: Callable[[np.ndarray], bool] | None = None,
        frame: str | None = None,
        rng: np.random.Generator | None = None,
    ) -> IKResult:
        """Joint angles that put `frame` (default the TCP) at T_base_tcp, within the joint limits minus
        settings.margin_rad. Tries q_seed, then preferred_q (default home_q), then random restarts; the null-space
        pulls toward preferred_q. `accept(q)` may reject a solution (e.g. one in collision) and the search goes on.
        Never raises for an unreachable pose: the result says success=False with the best residual."""
        return solve_ik(
            self,
            np.asarray(T_base_tcp, dtype=np.float64),
            self._frame_id(frame or self.tcp_frame),
            q_seed=q_seed,
            preferred_q=self.home_q if preferred_q is None else np.asarray(preferred_q, dtype=np.float64),
            settings=settings or IKSettings(),
            accept=accept,
            rng=rng,
        )
