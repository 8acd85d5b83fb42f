"""Fake pyorbbecsdk objects reproducing what the Femto Bolt driver relies on, failures included.

FakeOrbbecSDK() stands in for the module: Context, Pipeline, Config, AlignFilter and the enums. Frames come from
`frames`, a list consumed by wait_for_frames (None entries are timeouts), or from the `stream` iterator;
make_frameset builds them with chosen device/system timestamps. Depth is uint16 with a depth scale, colour RGB or
MJPG bytes. Knobs: no device, several devices, access-denied on open (missing udev rules), depth-engine failure
on start.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import cv2
import numpy as np


class Enum:
    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return self.name


class VideoProfile:
    def __init__(self, w, h, fps, fmt, intrinsic=None, distortion=None):
        self.w, self.h, self.fps, self.fmt = w, h, fps, fmt
        self.intrinsic = intrinsic or SimpleNamespace(
            fx=0.6 * w, fy=0.6 * w, cx=w / 2 - 0.5, cy=h / 2 - 0.5, width=w, height=h
        )
        self.distortion = distortion or SimpleNamespace(k1=0.0, k2=0.0, k3=0.0, k4=0.0, k5=0.0, k6=0.0, p1=0.0, p2=0.0)

    def as_video_stream_profile(self):
        return self

    def get_width(self):
        return self.w

    def get_height(self):
        return self.h

    def get_fps(self):
        return self.fps

    def get_format(self):
        return Enum(self.fmt)

    def get_intrinsic(self):
        return self.intrinsic

    def get_distortion(self):
        return self.distortion


class ProfileList:
    def __init__(self, profiles):
        self.profiles = profiles

    def get_count(self):
        return len(self.profiles)

    def get_stream_profile_by_index(self, i):
        return self.profiles[i]


class VideoFrame:
    def __init__(self, data, w, h, fmt, device_us, system_us, depth_scale=1.0):
        self.data, self.w, self.h, self.fmt = data, w, h, fmt
        self.device_us, self.system_us, self.depth_scale = device_us, system_us, depth_scale

    def get_data(self):
        return self.data

    def get_width(self):
        return self.w

    def get_height(self):
        return self.h

    def get_format(self):
        return Enum(self.fmt)

    def get_timestamp_us(self):
        return self.device_us

    def get_system_timestamp_us(self):
        return self.system_us

    def get_depth_scale(self):
        return self.depth_scale


class FrameSet:
    def __init__(self, colour, depth):
        self.colour, self.depth = colour, depth

    def get_color_frame(self):
        return self.colour

    def get_depth_frame(self):
        return self.depth

    def as_frame_set(self):
        return self


def make_frameset(sdk, device_us, age_s=0.005, depth_offset_us=0, colour_fmt="RGB"):
    """Colour: a horizontal ramp; depth (at depth resolution, before alignment): 1.0 m with a 0 (invalid) block
    in the top-left corner, expressed in units of depth_scale mm."""
    cw, ch = sdk.colour_size
    dw, dh = sdk.depth_size
    rgb = np.zeros((ch, cw, 3), np.uint8)
    rgb[..., 0] = np.linspace(0, 255, cw, dtype=np.uint8)[None, :]
    data = rgb.ravel()
    if colour_fmt == "MJPG":
        data = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 98])[1].ravel()
    depth = np.full((dh, dw), int(1000 / sdk.depth_scale), np.uint16)
    depth[: dh // 4, : dw // 4] = 0
    system_us = int((time.time() - age_s) * 1e6)
    colour = VideoFrame(data, cw, ch, colour_fmt, device_us, system_us)
    depth_frame = VideoFrame(
        depth.view(np.uint8).ravel(), dw, dh, "Y16", device_us + depth_offset_us, system_us, sdk.depth_scale
    )
    return FrameSet(colour, depth_frame)


class FakeOrbbecSDK:
    def __init__(self, serials=("CL8F1234",), colour_size=(1280, 720), depth_size=(640, 576), colour_fmt="RGB"):
        sdk = self
        self.serials = list(serials)
        self.colour_size, self.depth_size = colour_size, depth_size
        self.depth_scale = 1.0
        self.open_error: Exception | None = None
        self.start_error: Exception | None = None
        self.frames: list = []
        self.stream = None  # optional iterator: framesets made when asked for (fresh host timestamps)
        self.log_calls: list = []
        self.pipelines: list = []
        self.colour_profiles = [VideoProfile(*colour_size, 30, colour_fmt), VideoProfile(1920, 1080, 30, "MJPG")]
        self.depth_profiles = [
            VideoProfile(*depth_size, 30, "Y16"),
            VideoProfile(320, 288, 30, "Y16"),
            VideoProfile(1024, 1024, 15, "Y16"),
        ]
        self.OBLogLevel = SimpleNamespace(WARNING=Enum("WARNING"), NONE=Enum("NONE"))
        self.OBSensorType = SimpleNamespace(COLOR_SENSOR=Enum("COLOR_SENSOR"), DEPTH_SENSOR=Enum("DEPTH_SENSOR"))
        self.OBStreamType = SimpleNamespace(COLOR_STREAM=Enum("COLOR_STREAM"))

        class DeviceList:
            def get_count(self):
                return len(sdk.serials)

            def get_device_serial_number_by_index(self, i):
                return sdk.serials[i]

            def get_device_by_index(self, i):
                return SimpleNamespace(serial=sdk.serials[i])

        class Context:
            def __init__(self):
                sdk.log_calls.append("Context()")

            @staticmethod
            def set_logger_to_file(level, path):
                sdk.log_calls.append(("set_logger_to_file", level.name, path))

            def query_devices(self):
                return DeviceList()

        class Config:
            def __init__(self):
                self.enabled = []

            def enable_stream(self, profile):
                self.enabled.append(profile)

        class Pipeline:
            def __init__(self, device):
                if sdk.open_error is not None:
                    raise sdk.open_error
                self.device, self.started, self.stopped, self.synced = device, False, False, False
                sdk.pipelines.append(self)

            def get_stream_profile_list(self, sensor):
                return ProfileList(sdk.colour_profiles if sensor.name == "COLOR_SENSOR" else sdk.depth_profiles)

            def enable_frame_sync(self):
                self.synced = True

            def start(self, config):
                if sdk.start_error is not None:
                    raise sdk.start_error
                self.config, self.started = config, True

            def stop(self):
                self.stopped = True

            def wait_for_frames(self, timeout_ms):
                if sdk.stream is not None:
                    return next(sdk.stream)
                if not sdk.frames:
                    time.sleep(min(timeout_ms, 5) / 1000)
                    return None
                return sdk.frames.pop(0)

        class AlignFilter:
            """Software D2C: depth resampled onto the colour grid (nearest), timestamps kept."""

            def __init__(self, align_to_stream):
                self.target = align_to_stream

            def process(self, frames):
                d, c = frames.get_depth_frame(), frames.get_color_frame()
                raw = np.frombuffer(np.asarray(d.data).tobytes(), np.uint16).reshape(d.h, d.w)
                aligned = cv2.resize(raw, (c.w, c.h), interpolation=cv2.INTER_NEAREST)
                depth = VideoFrame(
                    aligned.view(np.uint8).ravel(), c.w, c.h, "Y16", d.device_us, d.system_us, d.depth_scale
                )
                return FrameSet(c, depth)

        self.Context, self.Config, self.Pipeline, self.AlignFilter = Context, Config, Pipeline, AlignFilter
