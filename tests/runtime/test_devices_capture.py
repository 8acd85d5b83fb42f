"""Captures carry the camera pose they were taken from: fixed, or on the flange (eye-in-hand) at the measured joints."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calibration.store import HandEyeCalibration, save_calibration
from drivers.sim.world import camera_mount_pose
from drivers.types import JointState, RGBDFrame
from runtime.devices import CaptureError, Devices, open_devices
from runtime.run.verification import camera_moved


def table_height_m(frame: RGBDFrame) -> float:
    """Median base-frame height of the pixels near z = 0 (the table top), and most pixels must be there."""
    points = frame.intrinsics.unproject_depth_image(frame.depth).reshape(-1, 3)
    z = (points @ frame.T_base_camera[:3, :3].T + frame.T_base_camera[:3, 3])[:, 2]
    z = z[np.isfinite(z)]
    table = np.abs(z) < 0.02
    assert table.mean() > 0.3
    return float(np.median(z[table]))


def test_eye_in_hand_capture_follows_the_arm(sim_profile_with, tmp_path):
    flange = {"camera": {"min_depth_m": 0.15, "sim": {"mount": "flange"}}}  # the table is near the hand
    T_flange_camera = camera_mount_pose(sim_profile_with(flange).camera)
    path = tmp_path / "hand_eye.yaml"
    calibration = HandEyeCalibration(
        mode="eye_in_hand", T=tuple(map(tuple, T_flange_camera)), created=dt.datetime.now(dt.UTC)
    )
    save_calibration(calibration, path)
    profile = sim_profile_with({**flange, "calibration": {"file": str(path)}})
    with open_devices(profile) as dev:
        first = dev.capture()
        np.testing.assert_allclose(first.T_base_camera, dev.world.camera_pose(), atol=1e-6)
        assert abs(table_height_m(first)) < 0.002
        q = dev.arm.read_state().q.copy()
        q[0] += 0.3  # turn the base joint: the camera swings with the arm
        for s in np.linspace(0.0, 1.0, 50)[1:]:
            dev.arm.servo(dev.arm.read_state().q + s * (q - dev.arm.read_state().q))
            dev.world.step(0.02)
        dev.world.step(0.5)
        second = dev.capture()
        shift = np.linalg.norm(second.T_base_camera[:3, 3] - first.T_base_camera[:3, 3])
        assert shift > 0.05
        np.testing.assert_allclose(second.T_base_camera, dev.world.camera_pose(), atol=1e-6)
        assert abs(table_height_m(second)) < 0.002


class MovingArm:
    """read_state reports the arm a little further along at every call."""

    def __init__(self) -> None:
        self.calls = 0

    def read_state(self) -> JointState:
        self.calls += 1
        return JointState(tuple(f"joint{i}" for i in range(1, 8)), np.full(7, 0.01 * self.calls), np.zeros(7), 0.0)


class StillCamera:
    def read(self, timeout_s: float | None = None) -> str:
        return "frame"


def test_eye_in_hand_capture_refuses_a_frame_taken_while_the_arm_moved():
    dev = Devices(StillCamera(), MovingArm(), None, lambda q: np.eye(4), moving_camera=True)
    with pytest.raises(CaptureError, match=r"moved 0\.0100 rad while the frame was taken"):
        dev.capture()


def test_capture_without_extrinsics_is_refused():
    dev = Devices(StillCamera(), MovingArm(), None, None)
    with pytest.raises(RuntimeError, match="without camera extrinsics"):
        dev.capture()


def test_camera_motion_between_captures_is_measured():
    T = np.eye(4)
    moved = T.copy()
    moved[:3, :3] = Rotation.from_euler("z", 1.0, degrees=True).as_matrix()
    moved[:3, 3] = [0.003, 0.004, 0.0]
    mm, deg = camera_moved(T, moved)
    assert mm == pytest.approx(5.0) and deg == pytest.approx(1.0)
    assert camera_moved(T, T) == (0.0, 0.0)
