"""Progress along a validated trajectory, re-timed with Ruckig without ever leaving its path.

The executor commands q(tau), where tau is trajectory time advancing at rate r = dtau/dt: r = 1 replays the
trajectory as timed; after a late driver call the arm has stopped, so r restarts from the measured speed and a
1-DoF Ruckig profile (velocity interface) ramps it back to 1; on abort the same profile brings r to 0. Positions
always lie on the validated polyline (linear between consecutive samples), so re-timing never produces a
configuration the gate has not seen and never jumps. The bounds on dr/dt and d2r/dt2 come from the path's
largest joint speed, so the added joint acceleration and jerk stay within the configured limits.
"""

from __future__ import annotations

import numpy as np
from ruckig import ControlInterface, InputParameter, OutputParameter, Result, Ruckig

from motion.limits import MotionLimits
from safety.trajectory import JointTrajectory


class PathClock:
    def __init__(self, trajectory: JointTrajectory, limits: MotionLimits, period_s: float) -> None:
        self.trajectory = trajectory
        self.period_s = period_s
        self.tau = 0.0  # trajectory time [s]
        self.rate = 1.0  # dtau/dt
        self._end = trajectory.duration_s
        peak = np.max(np.abs(trajectory.derivative(1)), axis=0)  # largest speed per joint [rad/s]
        moving = peak > 1e-9
        self.max_rate_accel = float(np.min(limits.acceleration[moving] / peak[moving])) if moving.any() else 1e3
        self.max_rate_jerk = float(np.min(limits.jerk[moving] / peak[moving])) if moving.any() else 1e5
        self._otg = Ruckig(1, period_s)
        self._inp = InputParameter(1)
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.max_velocity, self._inp.max_acceleration = [2.0], [self.max_rate_accel]
        self._inp.max_jerk = [self.max_rate_jerk]
        self._out = OutputParameter(1)
        self._target: float | None = None  # rate being approached by Ruckig; None: nominal replay

    @property
    def finished(self) -> bool:
        return self.tau >= self._end

    @property
    def stopping(self) -> bool:
        return self._target == 0.0

    @property
    def at_rest(self) -> bool:
        """Stopped by a profile (rate reached 0) or at the end of the trajectory."""
        return self.finished or (self.stopping and self.rate <= 1e-12)

    def _profile(self, target_rate: float, rate_now: float, rate_accel: float) -> None:
        self._inp.current_position = [self.tau]
        self._inp.current_velocity = [rate_now]
        self._inp.current_acceleration = [rate_accel]
        self._inp.target_velocity, self._inp.target_acceleration = [target_rate], [0.0]
        self._target = target_rate
        self.rate = rate_now

    def retime(self, measured_qd: np.ndarray) -> None:
        """Restart from the measured joint velocity (projected onto the path direction) and ramp back to the
        nominal rate; used after a late call, when the arm has braked on its own."""
        if self.stopping:
            return
        tangent = self.tangent(self.tau)
        norm2 = float(tangent @ tangent)
        rate_now = float(np.clip(measured_qd @ tangent / norm2, 0.0, 1.0)) if norm2 > 1e-12 else 1.0
        self._profile(1.0, rate_now, 0.0)

    def stop(self) -> None:
        """Bring the rate to 0 with a jerk-limited profile: the arm halts on the path."""
        if not self.stopping:
            accel = self._out.new_acceleration[0] if self._target is not None else 0.0
            self._profile(0.0, self.rate, accel)

    def advance(self) -> float:
        """Move tau on by one period; returns the new tau."""
        if self._target is None:
            self.tau = min(self.tau + self.period_s, self._end)
            return self.tau
        result = self._otg.update(self._inp, self._out)
        if result not in (Result.Working, Result.Finished):
            raise RuntimeError(f"Ruckig re-timing failed ({result}) at tau={self.tau:.4f} s, rate={self.rate:.3f}")
        self._out.pass_to_input(self._inp)
        self.tau = min(float(self._out.new_position[0]), self._end)
        self.rate = max(float(self._out.new_velocity[0]), 0.0)
        if result == Result.Finished and self._target == 1.0:
            self._target, self.rate = None, 1.0
        return self.tau

    def position(self, tau: float) -> np.ndarray:
        """q(tau): linear between the two samples around tau (the validated polyline)."""
        q = self.trajectory.positions
        x = tau / self.trajectory.dt
        k = int(np.floor(x + 1e-9))
        if k >= len(q) - 1:
            return q[-1].copy()
        s = max(x - k, 0.0)
        return q[k] if s < 1e-9 else (1 - s) * q[k] + s * q[k + 1]

    def tangent(self, tau: float) -> np.ndarray:
        """dq/dtau of the segment holding tau [rad/s]."""
        q, dt = self.trajectory.positions, self.trajectory.dt
        k = min(int(np.floor(tau / dt + 1e-9)), len(q) - 2)
        return (q[k + 1] - q[k]) / dt if k >= 0 else np.zeros(q.shape[1])
