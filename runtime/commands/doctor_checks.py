"""The items of `goalvla doctor`, one function each: what was found, whether it passes, and how to fix it.

A device that does not connect fails every item that needs it (nothing is assumed about a device not seen).
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata as md
import io
import itertools
import threading
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from runtime.config import Profile

MIN_FIRMWARE = (1, 10, 0)  # servo streaming behaviour the driver relies on
RATE_TOLERANCE = 0.9  # measured fps >= 90 % of the configured rate
RATE_FRAMES = 20
ESTOP_ROUND_TRIP_MAX_S = 0.2
REPORT_WINDOW_S = 0.3
REPORT_MIN_HZ = 80.0
PACKAGES = {  # distribution -> import name
    "numpy": "numpy",
    "opencv-python-headless": "cv2",
    "mujoco": "drivers.sim.gl",  # imports mujoco after choosing the off-screen GL backend
    "pin": "pinocchio",
    "eclipse-zenoh": "zenoh",
    "pydantic": "pydantic",
    "xarm-python-sdk": "xarm",
    "pyorbbecsdk2": "pyorbbecsdk",
}
EXTRA_PINS = {"pyorbbecsdk2": "2.1.2"}  # installed by setup.sh with --no-deps, so not in pyproject.toml
PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"
HARDWARE_ONLY = {"xarm-python-sdk": "xarm7", "pyorbbecsdk2": "femto_bolt"}


@dataclass(frozen=True)
class Check:
    item: str
    ok: bool | None  # None: not applicable here (e.g. controller settings on the sim)
    detail: str
    hint: str = ""


def pinned_versions(pyproject: Path = PYPROJECT) -> dict[str, str]:
    """name -> version of every `name==version` dependency in pyproject.toml, plus pyorbbecsdk2 (installed apart)."""
    pins = dict(EXTRA_PINS)
    if pyproject.exists():
        for dep in tomllib.loads(pyproject.read_text())["project"]["dependencies"]:
            name, sep, version = dep.partition("==")
            if sep:
                pins[name.strip()] = version.strip()
    return pins


def check_packages(profile: Profile, pins: dict[str, str] | None = None) -> list[Check]:
    """Installed, importable, and at the pinned version (the combination that was tested together)."""
    pins = pinned_versions() if pins is None else pins
    problems, versions = [], []
    for dist, module in PACKAGES.items():
        needed = HARDWARE_ONLY.get(dist) in (None, profile.robot.kind, profile.camera.kind)
        try:
            version = md.version(dist)
            if needed:
                with contextlib.redirect_stdout(io.StringIO()):  # the xArm SDK prints its version on import
                    importlib.import_module(module)
        except Exception as e:
            if needed:
                problems.append(f"{dist}: {type(e).__name__}: {e}")
            continue
        versions.append(f"{dist} {version}")
        if needed and dist in pins and version != pins[dist]:
            problems.append(f"{dist} {version} installed, {pins[dist]} pinned")
    import cv2

    if not hasattr(cv2, "calibrateHandEye") or not cv2.__version__.startswith("4."):
        problems.append(f"OpenCV {cv2.__version__} has no calibrateHandEye (needs 4.x)")
    hint = "run ./setup.sh (pyorbbecsdk2: `pip install --no-deps pyorbbecsdk2==2.1.2`; OpenCV pinned to 4.x)"
    return [Check("packages", not problems, "; ".join(problems) or ", ".join(versions), hint if problems else "")]


def check_camera(camera: Any, expected_fps: float, simulated: bool = False) -> list[Check]:
    from drivers.femto_bolt import intrinsics_problems

    try:
        camera.connect()
    except Exception as e:
        hint = "see the message; `lsusb | grep 2bc5`, udev rules, USB 3 port"
        return [
            Check("camera found", False, f"{type(e).__name__}: {e}", hint),
            Check("camera streaming", False, "camera not connected"),
            Check("intrinsics sane", False, "camera not connected"),
        ]
    out = [Check("camera found", True, getattr(camera, "serial", "") or type(camera).__name__)]
    try:
        stamps = [camera.read().stamp_s for _ in range(RATE_FRAMES)]
        span = stamps[-1] - stamps[0]
        fps = (len(stamps) - 1) / span if span > 0 else 0.0  # frames must advance in device time
        gaps = sum(1 for a, b in itertools.pairwise(stamps) if b - a > 1.5 / expected_fps)
        ok = fps >= RATE_TOLERANCE * expected_fps and gaps == 0
        if simulated:  # the simulated camera renders on demand: its rate is this machine's render speed
            ok = None if fps > 0 else False
        out.append(
            Check(
                "camera streaming",
                ok,
                f"{fps:.1f} fps by device time (expected {expected_fps}), {gaps} gaps over {RATE_FRAMES} frames",
                "" if ok is not False else "use a USB 3 port and the camera's own power supply; close other viewers",
            )
        )
    except Exception as e:
        out.append(Check("camera streaming", False, f"{type(e).__name__}: {e}", "check cable, power and udev"))
    problems = intrinsics_problems(camera.intrinsics)
    K = camera.intrinsics
    out.append(
        Check(
            "intrinsics sane",
            not problems,
            "; ".join(problems) or f"{K.width}x{K.height} fx {K.fx:.1f} fy {K.fy:.1f} cx {K.cx:.1f} cy {K.cy:.1f}",
            "the device calibration looks wrong: contact Orbbec / re-flash" if problems else "",
        )
    )
    return out


def _version_tuple(text: str) -> tuple[int, ...]:
    import re

    found = re.search(r"(\d+)\.(\d+)\.(\d+)", text)
    return tuple(int(v) for v in found.groups()) if found else ()


def check_arm(arm: Any) -> list[Check]:
    names = ("state reports", "firmware version", "errors and warnings", "mode and state", "controller safety settings")
    try:
        arm.connect()
    except Exception as e:
        return [
            Check(
                "arm reachable",
                False,
                f"{type(e).__name__}: {e}",
                "ping the controller; PC on the robot subnet (e.g. 192.168.1.10/24); e-stop released",
            )
        ] + [Check(n, False, "arm not connected") for n in names]
    api = getattr(arm, "api", None)
    out = [Check("arm reachable", True, f"{type(arm).__name__} connected")]
    if api is None:  # the simulated arm has no controller to interrogate
        fault = arm.read_state().fault_code
        out += [Check(n, None, "simulated arm") for n in names[:2]]
        out.append(Check("errors and warnings", fault == 0, f"fault code {fault}", "clear_fault()" if fault else ""))
        out += [Check(n, None, "simulated arm") for n in names[3:]]
        return out
    from drivers.xarm7.arm import READY_STATES, SERVO_MODE
    from drivers.xarm7.codes import controller_codes
    from drivers.xarm7.controller_safety import verify

    count = arm.report_count
    time.sleep(REPORT_WINDOW_S)
    hz = (arm.report_count - count) / REPORT_WINDOW_S
    ok = hz >= REPORT_MIN_HZ
    out.append(
        Check(
            "state reports",
            ok,
            f"{hz:.0f} Hz (report_type 'real', nominal 100 Hz)",
            "" if ok else "TCP port 30003 blocked (firewall)? wired link to the controller?",
        )
    )
    version = _version_tuple(arm.firmware_version)
    ok = bool(version) and version >= MIN_FIRMWARE
    out.append(
        Check(
            "firmware version",
            ok,
            arm.firmware_version or "unknown",
            "" if ok else f"update the controller firmware to >= {'.'.join(map(str, MIN_FIRMWARE))}",
        )
    )
    error, warning = controller_codes(api)
    out.append(
        Check(
            "errors and warnings",
            error == 0 and warning == 0,
            f"error {error}, warning {warning}",
            "" if not (error or warning) else "see the xArm manual for the code; fix the cause, clear_fault()",
        )
    )
    ok = api.mode == SERVO_MODE and api.state in READY_STATES
    out.append(
        Check(
            "mode and state",
            ok,
            f"mode {api.mode}, state {api.state}",
            "" if ok else "e-stop released? another program (xArm Studio) holding the arm?",
        )
    )
    from safety.robot_model import RobotModel

    robot = RobotModel(arm.spec)
    problems = verify(api, arm.controller_safety, lambda q: robot.tcp_pose(q)[:3, 3])
    s = arm.controller_safety
    out.append(
        Check(
            "controller safety settings",
            not problems,
            "; ".join(problems)
            or f"fence {list(s.tcp_boundary_mm)} mm, {s.max_joint_speed_deg_s:.0f} deg/s, "
            f"{s.max_tcp_speed_mm_s:.0f} mm/s, TCP +{s.tcp_offset_mm[2]:.0f} mm (reported TCP matches the model), "
            f"collision sensitivity {s.collision_sensitivity}",
            "firmware too old for reduced mode, or another client changed them" if problems else "",
        )
    )
    return out


def check_estop_round_trip(profile: Profile) -> Check:
    """Publish an e-stop from a connecting node to a listening one on the profile's endpoint and time it."""
    from runtime.messaging.bus import Bus
    from runtime.messaging.messages import EStop

    cfg, robot_id = profile.runtime.zenoh, profile.runtime.robot_id
    received = threading.Event()
    try:
        with Bus(cfg, robot_id, "listen") as listener, Bus(cfg, robot_id, "connect") as sender:
            listener.subscribe(
                listener.keys.estop, EStop, lambda key, msg: received.set() if msg.source == "doctor" else None
            )
            deadline = time.monotonic() + 3.0
            t0 = time.monotonic()
            while not received.is_set() and time.monotonic() < deadline:  # the link comes up asynchronously
                t0 = time.monotonic()
                sender.publish(sender.keys.estop, EStop(stamp_s=time.time(), source="doctor", reason="doctor test"))
                received.wait(0.1)
            round_trip = time.monotonic() - t0
    except ConnectionError as e:
        return Check(
            "e-stop over Zenoh",
            False,
            str(e),
            "is a runtime already listening there (stop it first)? TLS files present? endpoint address?",
        )
    if not received.is_set():
        return Check(
            "e-stop over Zenoh",
            False,
            f"no e-stop received on {cfg.endpoint} within 3 s",
            "firewall or ACL blocking the estop key?",
        )
    ok = round_trip <= ESTOP_ROUND_TRIP_MAX_S
    return Check(
        "e-stop over Zenoh",
        ok,
        f"{1000 * round_trip:.1f} ms on {cfg.endpoint}",
        "" if ok else "network latency too high for the e-stop path",
    )


def check_calibration(profile: Profile) -> Check:
    from calibration.store import CalibrationError, load_calibration

    cal = profile.calibration
    if cal.file is None:
        if profile.camera.kind == "sim":
            return Check("calibration", True, "sim: the simulated camera's true pose is used")
        return Check("calibration", False, "calibration.file is not set", "run `goalvla calibrate hand-eye`")
    try:
        stored = load_calibration(cal.file)
    except CalibrationError as e:
        return Check("calibration", False, str(e).splitlines()[0], "run `goalvla calibrate hand-eye`")
    age = stored.age_days()
    problems = []
    if stored.mode != cal.mode:
        problems.append(f"file is {stored.mode}, profile wants {cal.mode}")
    if age > cal.max_age_days:
        problems.append(f"{age:.0f} days old (limit {cal.max_age_days:.0f})")
    quality = f", median residual {stored.residual_mm:.2f} mm" if stored.residual_mm is not None else ""
    return Check(
        "calibration",
        not problems,
        "; ".join(problems) or f"{stored.mode}, {age:.1f} days old, {stored.poses} views, {stored.method}{quality}",
        "recalibrate: `goalvla calibrate hand-eye`" if problems else "",
    )
