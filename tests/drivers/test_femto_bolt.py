"""FemtoBolt against fake pyorbbecsdk objects: stream choice, alignment, units, timestamps, staleness, errors."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest
from fake_orbbec import FakeOrbbecSDK, VideoProfile, make_frameset

from drivers.config import CameraConfig
from drivers.errors import CameraTimeoutError, DeviceNotFoundError, StaleFrameError
from drivers.femto_bolt import CameraSetupError, FemtoBolt, intrinsics_problems
from drivers.femto_bolt import camera as femto_camera
from drivers.femto_bolt.streams import StreamSelectionError
from drivers.types import CameraIntrinsics

PERIOD_US = 33_333


@pytest.fixture(autouse=True)
def log_dir(tmp_path, monkeypatch):
    monkeypatch.setattr(femto_camera, "SDK_LOG_DIR", tmp_path / "orbbec-log")


def config(**kw) -> CameraConfig:
    base = {"kind": "femto_bolt", "width_px": 1280, "height_px": 720, "read_timeout_s": 0.3}
    return CameraConfig(**{**base, **kw})


def test_connect_selects_nfov_and_colour_with_sync_and_redirects_the_sdk_log(tmp_path):
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    pipeline = sdk.pipelines[0]
    enabled = [(p.w, p.h, p.fmt) for p in pipeline.config.enabled]
    assert enabled == [(640, 576, "Y16"), (1280, 720, "RGB")]
    assert pipeline.synced and pipeline.started
    assert sdk.log_calls[0] == ("set_logger_to_file", "WARNING", str(tmp_path / "orbbec-log"))
    assert cam.serial == "CL8F1234"
    cam.close()
    assert pipeline.stopped and not cam.is_connected
    cam.close()  # idempotent


def test_depth_mode_is_configurable_and_checked():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(depth_mode="NFOV_BINNED"), sdk)
    cam.connect()
    assert (sdk.pipelines[0].config.enabled[0].w, sdk.pipelines[0].config.enabled[0].h) == (320, 288)
    with pytest.raises(StreamSelectionError, match="at most 15 fps"):
        FemtoBolt(config(depth_mode="WFOV_UNBINNED"), FakeOrbbecSDK()).connect()


def test_frame_in_metres_aligned_to_colour_with_nan_for_invalid():
    sdk = FakeOrbbecSDK()
    sdk.depth_scale = 0.5  # raw units of 0.5 mm: the driver must apply the scale
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 1_000_000)]
    frame = cam.read()
    assert frame.rgb.shape == (720, 1280, 3) and frame.depth.shape == (720, 1280)
    assert frame.depth.dtype == np.float32
    assert np.isnan(frame.depth[:100, :200]).all()  # raw 0 -> NaN, carried through the alignment
    assert np.nanmedian(frame.depth) == pytest.approx(1.0)
    assert frame.stamp_s == pytest.approx(1.0)  # device timestamp, not host time
    assert frame.rgb[10, 0, 0] < frame.rgb[10, -1, 0]  # colour decoded in order


def test_resize_scales_intrinsics_consistently():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(width_px=640, height_px=360), sdk)  # no 640x360 mode: 1280x720 downscaled
    cam.connect()
    native = CameraIntrinsics(1280, 720, 768.0, 768.0, 639.5, 359.5)
    assert cam.intrinsics == native.resized(640, 360)
    sdk.frames = [make_frameset(sdk, 1_000_000)]
    frame = cam.read()
    assert frame.rgb.shape == (360, 640, 3) and frame.intrinsics == cam.intrinsics


def test_intrinsics_reported_for_another_resolution_are_scaled():
    sdk = FakeOrbbecSDK()
    sdk.colour_profiles[0].intrinsic = SimpleNamespace(
        fx=1536.0, fy=1536.0, cx=1279.5, cy=719.5, width=2560, height=1440
    )
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    assert cam.intrinsics.fx == pytest.approx(768.0) and cam.intrinsics.cx == pytest.approx(639.5)


def test_distortion_is_removed_so_the_pinhole_intrinsics_hold():
    sdk = FakeOrbbecSDK()
    sdk.colour_profiles[0].distortion = SimpleNamespace(
        k1=0.08, k2=-0.05, k3=0.0, k4=0.0, k5=0.0, k6=0.0, p1=0.0, p2=0.0
    )
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 1_000_000)]
    frame = cam.read()
    # barrel correction moves the ramp: the undistorted colour differs from the raw one near the edges
    raw = np.linspace(0, 255, 1280, dtype=np.uint8)
    assert abs(int(frame.rgb[360, 100, 0]) - int(raw[100])) > 2
    assert abs(int(frame.rgb[360, 640, 0]) - int(raw[640])) <= 1  # the centre does not move


def test_mjpg_colour_is_decoded():
    sdk = FakeOrbbecSDK(colour_fmt="MJPG")
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 1_000_000, colour_fmt="MJPG")]
    frame = cam.read()
    assert abs(int(frame.rgb[10, 640, 0]) - 127) < 4


def test_old_repeated_and_unsynchronised_frames_are_skipped():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 2_000_000)]
    assert cam.read().stamp_s == pytest.approx(2.0)
    sdk.frames = [
        None,  # timeout of one wait
        make_frameset(sdk, 2_000_000),  # the same frame again
        make_frameset(sdk, 2_000_000 + PERIOD_US, depth_offset_us=PERIOD_US),  # depth from the next exposure
        make_frameset(sdk, 2_000_000 + 2 * PERIOD_US),
    ]
    assert cam.read().stamp_s == pytest.approx(2.0 + 2 * PERIOD_US * 1e-6)


def test_stale_frames_raise_after_the_timeout():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(max_frame_age_s=0.2), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 3_000_000 + k * PERIOD_US, age_s=0.5) for k in range(3)]
    with pytest.raises(StaleFrameError, match=r"0\.5\d* s old"):
        cam.read(timeout_s=0.1)


def test_no_frames_is_a_timeout():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    with pytest.raises(CameraTimeoutError, match="no new synchronised frame"):
        cam.read(timeout_s=0.05)


def test_missing_device_timestamps_fall_back_to_host_time():
    sdk = FakeOrbbecSDK()
    cam = FemtoBolt(config(), sdk)
    cam.connect()
    sdk.frames = [make_frameset(sdk, 0, age_s=0.01)]
    frame = cam.read()
    assert abs(frame.stamp_s - (time.time() - 0.01)) < 0.5  # the host arrival time, not 0


def test_no_device_and_wrong_serial():
    with pytest.raises(DeviceNotFoundError, match="no Orbbec camera on USB"):
        FemtoBolt(config(), FakeOrbbecSDK(serials=())).connect()
    with pytest.raises(DeviceNotFoundError, match="attached: CL8F1234"):
        FemtoBolt(config(serial="XYZ"), FakeOrbbecSDK()).connect()
    with pytest.raises(CameraSetupError, match=r"set camera\.serial"):
        FemtoBolt(config(), FakeOrbbecSDK(serials=("A", "B"))).connect()


def test_missing_udev_rules_is_explained():
    sdk = FakeOrbbecSDK()
    sdk.open_error = RuntimeError("usbEnumerator: failed to open device, OB_USB_STATUS_ACCESS")
    cam = FemtoBolt(config(), sdk)
    with pytest.raises(CameraSetupError, match="udev rules"):
        cam.connect()
    assert not cam.is_connected


def test_depth_engine_failure_is_explained_and_rolled_back():
    sdk = FakeOrbbecSDK()
    sdk.start_error = RuntimeError("Depth engine create and initialize failed! EGL NO DISPLAY")
    cam = FemtoBolt(config(), sdk)
    with pytest.raises(CameraSetupError, match="needs OpenGL"):
        cam.connect()
    assert sdk.pipelines[0].stopped and not cam.is_connected


def test_unsupported_colour_size_lists_the_offered_modes():
    sdk = FakeOrbbecSDK()
    sdk.colour_profiles = [VideoProfile(1280, 720, 30, "RGB")]
    with pytest.raises(StreamSelectionError, match=r"offered: 1280x720@30 RGB"):
        FemtoBolt(config(width_px=2048, height_px=1536), sdk).connect()


def test_intrinsics_sanity():
    good = CameraIntrinsics(1280, 720, 763.0, 763.0, 639.5, 359.5)  # 80 deg horizontal
    assert intrinsics_problems(good) == []
    assert any("field of view" in p for p in intrinsics_problems(CameraIntrinsics(1280, 720, 300, 300, 639.5, 359.5)))
    assert any("square" in p for p in intrinsics_problems(CameraIntrinsics(1280, 720, 763, 700, 639.5, 359.5)))
    assert any("centre" in p for p in intrinsics_problems(CameraIntrinsics(1280, 720, 763, 763, 100, 359.5)))
