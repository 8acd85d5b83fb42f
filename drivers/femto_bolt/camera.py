"""Orbbec Femto Bolt on pyorbbecsdk (PyPI pyorbbecsdk2): synchronised colour + depth, depth aligned to colour in
software (the Bolt has no hardware D2C), undistorted, in metres with NaN for invalid pixels.

The colour image is undistorted with the device's own calibration so the frame's pinhole intrinsics hold (the
contract of RGBDFrame); aligned depth follows with nearest-neighbour sampling. Frames are paired and ordered by
device timestamp; a frame whose host arrival time is older than camera.max_frame_age_s is stale.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from drivers.config import CameraConfig
from drivers.errors import CameraTimeoutError, DeviceNotFoundError, DriverError, NotConnectedError, StaleFrameError
from drivers.femto_bolt import streams
from drivers.interfaces import Camera
from drivers.types import CameraIntrinsics, RGBDFrame

log = logging.getLogger(__name__)

SDK_LOG_DIR = Path.home() / ".cache" / "goalvla" / "orbbec-log"  # the SDK writes ./Log otherwise
UDEV_HINT = (
    "the camera is present but not accessible: install the Orbbec udev rules (99-obsensor-libusb.rules, shipped "
    "inside the pyorbbecsdk package under shared/), `sudo udevadm control --reload && sudo udevadm trigger`, "
    "then re-plug the camera"
)
DEPTH_ENGINE_HINT = (
    "the Femto Bolt depth engine needs OpenGL: on a headless host install libegl1 and libgl1-mesa-dri (EGL) or "
    "run with a display; check that `eglinfo` lists a device"
)


class CameraSetupError(DriverError):
    """The camera is there but cannot be opened or started; the message says how to fix it."""


def explain(e: BaseException) -> DriverError:
    """Map an SDK exception to a driver error with a fix."""
    text = str(e)
    low = text.lower()
    if "no device" in low:
        return DeviceNotFoundError(f"no Orbbec camera found ({text}): check the USB 3 cable and `lsusb | grep 2bc5`")
    if any(k in low for k in ("access", "permission", "denied", "libusb_error_access")):
        return CameraSetupError(f"{UDEV_HINT} ({text})")
    if any(k in low for k in ("depth engine", "egl", "opengl", "glfw")):
        return CameraSetupError(f"{DEPTH_ENGINE_HINT} ({text})")
    return CameraSetupError(f"Femto Bolt: {text}")


def import_sdk() -> Any:
    import pyorbbecsdk

    return pyorbbecsdk


class FemtoBolt(Camera):
    def __init__(self, config: CameraConfig, sdk: Any = None) -> None:
        self.config = config
        self._sdk = sdk
        self._pipeline: Any = None
        self._align: Any = None
        self._intrinsics: CameraIntrinsics | None = None
        self._maps: tuple[np.ndarray, np.ndarray] | None = None
        self._native: CameraIntrinsics | None = None
        self._last_device_us = -1
        self._frame_id = 0
        self.serial = ""
        self.streams: tuple[streams.Profile, streams.Profile] | None = None

    @property
    def is_connected(self) -> bool:
        return self._pipeline is not None

    @property
    def intrinsics(self) -> CameraIntrinsics:
        if self._intrinsics is None:
            raise NotConnectedError("FemtoBolt.intrinsics before connect()")
        return self._intrinsics

    # -- lifecycle ----------------------------------------------------------------------------------------
    def connect(self) -> None:
        if self._pipeline is not None:
            return
        sdk = self._sdk or import_sdk()
        SDK_LOG_DIR.mkdir(parents=True, exist_ok=True)
        sdk.Context.set_logger_to_file(sdk.OBLogLevel.WARNING, str(SDK_LOG_DIR))
        pipeline = None
        try:
            device = self._find_device(sdk)
            pipeline = sdk.Pipeline(device)
            depth = streams.choose_depth(
                streams.video_profiles(pipeline.get_stream_profile_list(sdk.OBSensorType.DEPTH_SENSOR)),
                self.config.depth_mode,
                self.config.fps,
            )
            colour = streams.choose_colour(
                streams.video_profiles(pipeline.get_stream_profile_list(sdk.OBSensorType.COLOR_SENSOR)),
                self.config.width_px,
                self.config.height_px,
                self.config.fps,
            )
            config = sdk.Config()
            config.enable_stream(depth.handle)
            config.enable_stream(colour.handle)
            pipeline.enable_frame_sync()
            pipeline.start(config)
            self._align = sdk.AlignFilter(align_to_stream=sdk.OBStreamType.COLOR_STREAM)
            self._set_geometry(colour)
        except (streams.StreamSelectionError, DriverError):
            self._stop(pipeline)
            raise
        except Exception as e:
            self._stop(pipeline)
            raise explain(e) from e
        self._pipeline, self.streams = pipeline, (colour, depth)
        self._last_device_us = -1
        log.info(
            "Femto Bolt %s: colour %dx%d %s, depth %s @ %d fps",
            self.serial,
            colour.width,
            colour.height,
            colour.format,
            self.config.depth_mode,
            self.config.fps,
        )

    def _find_device(self, sdk: Any) -> Any:
        devices = sdk.Context().query_devices()
        count = devices.get_count()
        if count == 0:
            raise DeviceNotFoundError(
                "no Orbbec camera on USB: check the cable (USB 3 port), the power supply and `lsusb | grep 2bc5`"
            )
        serials = [devices.get_device_serial_number_by_index(i) for i in range(count)]
        wanted = self.config.serial
        if wanted is None:
            if count > 1:
                raise CameraSetupError(f"{count} Orbbec cameras attached ({', '.join(serials)}): set camera.serial")
            index = 0
        elif wanted in serials:
            index = serials.index(wanted)
        else:
            raise DeviceNotFoundError(f"no Femto Bolt with serial {wanted}; attached: {', '.join(serials)}")
        self.serial = serials[index]
        return devices.get_device_by_index(index)

    def _set_geometry(self, colour: streams.Profile) -> None:
        """Intrinsics of the output image: the device's colour calibration, undistorted, resized to the config."""
        native = streams.intrinsics_of(colour.handle.get_intrinsic(), colour.width, colour.height)
        distortion = streams.distortion_of(colour.handle.get_distortion())
        self._native = native
        self._maps = None
        if np.any(distortion != 0):
            self._maps = cv2.initUndistortRectifyMap(
                native.K, distortion, None, native.K, (native.width, native.height), cv2.CV_32FC1
            )
        self._intrinsics = native.resized(self.config.width_px, self.config.height_px)

    def close(self) -> None:
        pipeline, self._pipeline = self._pipeline, None
        self._stop(pipeline)

    @staticmethod
    def _stop(pipeline: Any) -> None:
        if pipeline is None:
            return
        try:
            pipeline.stop()
        except Exception as e:
            log.warning("Femto Bolt: pipeline.stop() failed: %s", e)

    # -- frames -------------------------------------------------------------------------------------------
    def read(self, timeout_s: float | None = None) -> RGBDFrame:
        """Next synchronised pair newer than the last one; stale or unpaired frames are skipped until timeout."""
        if self._pipeline is None:
            raise NotConnectedError("FemtoBolt.read() before connect()")
        timeout_s = self.config.read_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        half_period_us = 0.5e6 / self.config.fps
        newest_age = None
        while (remaining := deadline - time.monotonic()) > 0:
            frames = self._pipeline.wait_for_frames(max(1, int(remaining * 1000)))
            if frames is None:
                continue
            colour, depth = frames.get_color_frame(), frames.get_depth_frame()
            if colour is None or depth is None:
                continue
            device_us, depth_us = colour.get_timestamp_us(), depth.get_timestamp_us()
            stamp_us = device_us or colour.get_system_timestamp_us()  # some hosts get no device timestamps
            if stamp_us <= self._last_device_us:
                continue  # not newer than the last frame
            if device_us and depth_us and abs(device_us - depth_us) > half_period_us:
                continue  # colour and depth from different exposures
            age = time.time() - colour.get_system_timestamp_us() * 1e-6
            if age > self.config.max_frame_age_s:
                newest_age = age
                continue
            aligned = self._align.process(frames)
            if aligned is None:
                continue
            self._last_device_us = stamp_us
            return self._frame(colour, aligned.as_frame_set().get_depth_frame(), stamp_us)
        if newest_age is not None:
            raise StaleFrameError(
                f"Femto Bolt frames arrive {newest_age:.3f} s old (limit "
                f"{self.config.max_frame_age_s} s): USB bandwidth or host load"
            )
        raise CameraTimeoutError(
            f"Femto Bolt: no new synchronised frame within {timeout_s:.2f} s "
            "(USB 3 link? power? another process holding the camera?)"
        )

    def _frame(self, colour: Any, depth: Any, stamp_us: int) -> RGBDFrame:
        native = self._native
        w, h = native.width, native.height
        rgb = streams.decode_colour(
            colour.get_data(), colour.get_width(), colour.get_height(), colour.get_format().name
        )
        raw = np.frombuffer(np.asarray(depth.get_data()).tobytes(), dtype=np.uint16)
        if raw.size != w * h or rgb.shape[:2] != (h, w):
            raise CameraSetupError(
                f"aligned frame sizes differ: colour {rgb.shape[1]}x{rgb.shape[0]}, "
                f"depth {raw.size} px, expected {w}x{h}"
            )
        metres = raw.reshape(h, w).astype(np.float32) * np.float32(depth.get_depth_scale() * 1e-3)
        if self._maps is not None:
            rgb = cv2.remap(rgb, *self._maps, cv2.INTER_LINEAR)
            metres = cv2.remap(metres, *self._maps, cv2.INTER_NEAREST)
        out = self._intrinsics
        if (out.width, out.height) != (w, h):
            rgb = cv2.resize(rgb, (out.width, out.height), interpolation=cv2.INTER_AREA)
            metres = cv2.resize(metres, (out.width, out.height), interpolation=cv2.INTER_NEAREST)
        metres[(metres < self.config.min_depth_m) | (metres > self.config.max_depth_m)] = np.nan  # 0 = invalid
        self._frame_id += 1
        return RGBDFrame(rgb, metres, out, stamp_us * 1e-6, self._frame_id)
