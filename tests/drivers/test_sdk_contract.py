"""The fakes must not drift from the installed SDKs: every call the drivers made on a fake binds to the real
XArmAPI method's signature, and every pyorbbecsdk name the Femto Bolt driver touches exists in the real module."""

from __future__ import annotations

import contextlib
import inspect
import io

import numpy as np
import pytest
from fake_xarm import FakeXArmAPI

from drivers.config import RobotConfig
from drivers.xarm7 import XArm7, XArmGripper
from drivers.xarm7.controller_safety import verify
from safety.config import SafetyConfig

with contextlib.redirect_stdout(io.StringIO()):  # the SDK prints its version on import
    from xarm.wrapper import XArmAPI

ob = pytest.importorskip("pyorbbecsdk")


def test_every_xarm_call_binds_to_the_real_sdk():
    fakes = []

    def factory(ip, **kw):
        fakes.append(FakeXArmAPI(ip, **kw))
        return fakes[-1]

    arm = XArm7(RobotConfig(kind="xarm7", ip="10.0.0.2"), SafetyConfig(), api_factory=factory)
    gripper = XArmGripper(arm)
    with arm:
        gripper.connect()
        arm.servo(np.zeros(7))
        arm.read_state()
        gripper.command(0.03)
        gripper.read_state()
        gripper.stop()
        verify(arm.api, arm.controller_safety)
        arm.stop()
        arm.clear_fault()
        arm.emergency_stop()
    api = fakes[0]
    inspect.signature(XArmAPI.__init__).bind(
        None, api.init["port"], **{k: v for k, v in api.init.items() if k != "port"}
    )
    for name, args, kwargs in api.calls:
        real = getattr(XArmAPI, name)
        inspect.signature(real).bind(None, *args, **kwargs)  # raises TypeError on a mismatch
    for prop in (
        "angles",
        "position",
        "error_code",
        "warn_code",
        "mode",
        "state",
        "connected",
    ):
        assert isinstance(inspect.getattr_static(XArmAPI, prop), property), prop


def test_every_orbbec_name_the_driver_uses_exists():
    used = {
        ob.Context: ("set_logger_to_file", "query_devices"),
        ob.DeviceList: ("get_count", "get_device_serial_number_by_index", "get_device_by_index"),
        ob.Pipeline: ("get_stream_profile_list", "enable_frame_sync", "start", "stop", "wait_for_frames"),
        ob.Config: ("enable_stream",),
        ob.StreamProfileList: ("get_count", "get_stream_profile_by_index"),
        ob.StreamProfile: ("as_video_stream_profile",),
        ob.VideoStreamProfile: ("get_width", "get_height", "get_fps", "get_format", "get_intrinsic", "get_distortion"),
        ob.Frame: ("as_frame_set", "get_data", "get_format", "get_timestamp_us", "get_system_timestamp_us"),
        ob.FrameSet: ("get_color_frame", "get_depth_frame"),
        ob.VideoFrame: ("get_width", "get_height"),
        ob.DepthFrame: ("get_depth_scale",),
    }
    missing = [f"{cls.__name__}.{name}" for cls, names in used.items() for name in names if not hasattr(cls, name)]
    assert missing == []
    assert ob.AlignFilter(align_to_stream=ob.OBStreamType.COLOR_STREAM) is not None
    assert {ob.OBFormat.RGB.name, ob.OBFormat.MJPG.name, ob.OBFormat.Y16.name} == {"RGB", "MJPG", "Y16"}
    assert all(hasattr(ob.OBCameraDistortion(), k) for k in ("k1", "k2", "k3", "k4", "k5", "k6", "p1", "p2"))
    assert all(hasattr(ob.OBCameraIntrinsic(), k) for k in ("fx", "fy", "cx", "cy", "width", "height"))
    assert hasattr(ob.OBLogLevel, "WARNING") and hasattr(ob.OBSensorType, "DEPTH_SENSOR")
