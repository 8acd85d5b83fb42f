"""Controller-side safety on the xArm, from the profile: the last layer of defence, enforced by the controller.

The runtime's gate already refuses anything outside the workspace or the speed limits; these settings make the
controller itself stop the arm (errors 31 collision, 35 fence) if something gets past it. The same values are
read back by `goalvla doctor` to show they were applied. Units at the SDK: mm, degrees.

The TCP offset cannot be read back (the 'real' report does not carry it; the SDK's `tcp_offset` stays zero), so
it is checked by its effect: the TCP position the controller reports must match the project's kinematics at the
reported joints.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.config import RobotConfig
from drivers.description import RobotSpec
from drivers.xarm7.codes import check

XARM_GRIPPER_TOOL_MODEL = 1  # set_collision_tool_model: 1 = xArm Gripper
TOLERANCE = {"mm": 1.0, "deg_s": 0.5, "mm_s": 1.0}
# Controller TCP vs the project's FK: each arm's factory calibration moves it by a few mm from the nominal model;
# a missing or mis-scaled offset (172 mm) or a wrong base frame is far outside.
TCP_TOLERANCE_MM = 5.0

TcpFromJoints = Callable[[np.ndarray], np.ndarray]  # joints [rad] -> TCP position in the base frame [m]


@dataclass(frozen=True)
class ControllerSafety:
    """What is written to the controller, in its units."""

    collision_sensitivity: int
    tcp_boundary_mm: tuple[float, float, float, float, float, float]  # x_max, x_min, y_max, y_min, z_max, z_min
    max_joint_speed_deg_s: float
    max_tcp_speed_mm_s: float
    tcp_offset_mm: tuple[float, float, float]
    payload_kg: float
    payload_cog_mm: tuple[float, float, float]

    @classmethod
    def from_profile(cls, robot: RobotConfig, safety: Any, spec: RobotSpec) -> ControllerSafety:
        """`safety` is the profile's SafetyConfig (workspace box, reduced speeds)."""
        lo, hi = np.asarray(safety.workspace.min_m) * 1000.0, np.asarray(safety.workspace.max_m) * 1000.0
        tcp = next(j for j in spec.fixed_joints if j.child == spec.tcp_link)
        return cls(
            collision_sensitivity=robot.collision_sensitivity,
            tcp_boundary_mm=tuple(float(v) for v in (hi[0], lo[0], hi[1], lo[1], hi[2], lo[2])),
            max_joint_speed_deg_s=math.degrees(safety.max_joint_velocity_rad_s),
            max_tcp_speed_mm_s=safety.max_tcp_speed_m_s * 1000.0,
            tcp_offset_mm=tuple(float(v) * 1000.0 for v in tcp.xyz),
            payload_kg=robot.payload_kg,
            payload_cog_mm=tuple(float(v) * 1000.0 for v in robot.payload_cog_m),
        )


def apply(api: Any, s: ControllerSafety) -> None:
    """Write every setting (controller in mode 0); the caller re-enters its mode and state afterwards."""
    check(api, "set_tcp_offset", api.set_tcp_offset([*s.tcp_offset_mm, 0.0, 0.0, 0.0], is_radian=False, wait=True))
    check(api, "set_tcp_load", api.set_tcp_load(s.payload_kg, list(s.payload_cog_mm)))
    check(api, "set_collision_sensitivity", api.set_collision_sensitivity(s.collision_sensitivity))
    check(api, "set_collision_tool_model", api.set_collision_tool_model(XARM_GRIPPER_TOOL_MODEL))
    check(api, "set_self_collision_detection", api.set_self_collision_detection(True))
    check(api, "set_reduced_max_joint_speed", api.set_reduced_max_joint_speed(s.max_joint_speed_deg_s, is_radian=False))
    check(api, "set_reduced_max_tcp_speed", api.set_reduced_max_tcp_speed(s.max_tcp_speed_mm_s))
    check(api, "set_reduced_tcp_boundary", api.set_reduced_tcp_boundary(list(s.tcp_boundary_mm)))
    check(api, "set_reduced_mode", api.set_reduced_mode(True))
    check(api, "set_fence_mode", api.set_fence_mode(True))
    check(api, "set_state", api.set_state(0))  # the SDK asks for set_state(0) after changing the sensitivity


def verify(api: Any, s: ControllerSafety, tcp_from_joints: TcpFromJoints | None = None) -> list[str]:
    """Read the settings back; returns a list of mismatches (empty: all applied). With `tcp_from_joints` the
    controller's reported TCP position is compared with it at the reported joints (the TCP offset's effect)."""
    states = check(api, "get_reduced_states", api.get_reduced_states(is_radian=False))
    problems: list[str] = []
    if not states or not states[0]:
        problems.append("reduced mode is off")
    if len(states) < 6 or not states[5]:
        problems.append("fence mode (TCP boundary) is off")
    if len(states) > 1 and not np.allclose(states[1], s.tcp_boundary_mm, atol=TOLERANCE["mm"]):
        problems.append(f"TCP boundary {list(states[1])} mm, expected {list(s.tcp_boundary_mm)} mm")
    if len(states) > 2 and states[2] > s.max_tcp_speed_mm_s + TOLERANCE["mm_s"]:
        problems.append(f"reduced TCP speed {states[2]} mm/s above {s.max_tcp_speed_mm_s} mm/s")
    if len(states) > 3 and states[3] > s.max_joint_speed_deg_s + TOLERANCE["deg_s"]:
        problems.append(f"reduced joint speed {states[3]} deg/s above {s.max_joint_speed_deg_s:.1f} deg/s")
    if tcp_from_joints is not None:
        reported = np.asarray(api.position, dtype=np.float64)[:3]
        expected = 1000.0 * np.asarray(tcp_from_joints(np.radians(np.asarray(api.angles, dtype=np.float64)[:7])))
        miss = float(np.linalg.norm(reported - expected))
        if miss > TCP_TOLERANCE_MM:
            problems.append(
                f"controller TCP at {np.round(reported, 1).tolist()} mm, the model puts it at "
                f"{np.round(expected, 1).tolist()} mm ({miss:.1f} mm apart): TCP offset {list(s.tcp_offset_mm)} mm "
                "not applied, or the wrong robot model"
            )
    return problems
