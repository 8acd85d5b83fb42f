"""The planned gripper poses drawn on the camera image, so the operator sees where the hand will go before
confirming: each TCP pose as its axes (x red, y green, approach z blue) and the two finger tips, labelled."""

from __future__ import annotations

import cv2
import numpy as np

from drivers.types import CameraIntrinsics

AXIS_M = 0.05
COLOURS_RGB = ((230, 40, 40), (40, 200, 40), (40, 90, 255))


def draw_tcp_poses(
    rgb: np.ndarray,
    intrinsics: CameraIntrinsics,
    T_base_camera: np.ndarray,
    poses: dict[str, np.ndarray],
    finger_gap_m: float = 0.085,
) -> np.ndarray:
    """A copy of rgb with every named TCP pose (4x4, base frame) drawn; poses behind the camera are skipped."""
    out = np.ascontiguousarray(rgb.copy())
    T_camera_base = np.linalg.inv(T_base_camera)
    for name, T_base_tcp in poses.items():
        T = T_camera_base @ T_base_tcp
        origin = T[:3, 3]
        half = finger_gap_m / 2
        tips = [origin + T[:3, 1] * s for s in (-half, half)]
        ends = [origin + T[:3, k] * AXIS_M for k in range(3)]
        pts = np.array([origin, *ends, *tips])
        if np.any(pts[:, 2] <= 0.05):
            continue
        uv = np.round(intrinsics.project(pts)).astype(int)
        o = tuple(uv[0])
        for k in range(3):
            cv2.line(out, o, tuple(uv[1 + k]), COLOURS_RGB[k], 2, cv2.LINE_AA)
        cv2.line(out, tuple(uv[4]), tuple(uv[5]), (255, 255, 255), 1, cv2.LINE_AA)
        for tip in uv[4:]:
            cv2.circle(out, tuple(tip), 4, (255, 220, 0), -1, cv2.LINE_AA)
        cv2.putText(out, name, (o[0] + 6, o[1] - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return out
