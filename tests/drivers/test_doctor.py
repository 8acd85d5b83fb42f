"""`goalvla doctor` against the fake SDKs (all good, then each failure shows up with a hint) and on the sim."""

from __future__ import annotations

import datetime as dt
import itertools
import socket

import numpy as np
from fake_orbbec import FakeOrbbecSDK, make_frameset
from fake_xarm import FakeXArmAPI
from rich.console import Console

from calibration.store import HandEyeCalibration, save_calibration
from drivers.femto_bolt import FemtoBolt
from drivers.femto_bolt import camera as femto_camera
from drivers.xarm7 import XArm7
from runtime.commands.doctor import render, run_checks, run_doctor
from runtime.commands.doctor_checks import check_packages, pinned_versions
from runtime.config import load_profile

PERIOD_US = 33_333


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def lab_profile(tmp_path, age_days=1.0, mode="eye_to_hand"):
    cal = tmp_path / "cal.yaml"
    created = dt.datetime.now(dt.UTC) - dt.timedelta(days=age_days)
    save_calibration(
        HandEyeCalibration(
            mode=mode, T=tuple(map(tuple, np.eye(4))), created=created, method="park", poses=15, residual_mm=1.2
        ),
        cal,
    )
    overrides = {
        "calibration": {"file": str(cal)},
        "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}", "tls": None, "access_control": None}},
    }
    return load_profile("configs/lab.yaml", overrides)


def fakes(profile, monkeypatch, tmp_path, period_us=PERIOD_US, setup_api=None):
    monkeypatch.setattr(femto_camera, "SDK_LOG_DIR", tmp_path / "log")
    sdk = FakeOrbbecSDK()
    sdk.stream = (make_frameset(sdk, 1_000_000 + k * period_us) for k in itertools.count())
    apis = []

    def api_factory(ip, **kw):
        api = FakeXArmAPI(ip, **kw)
        if setup_api:
            setup_api(api)
        apis.append(api)
        return api

    camera = FemtoBolt(profile.camera, sdk)
    arm = XArm7(profile.robot, profile.safety, api_factory=api_factory)
    return (lambda: camera), (lambda: arm), apis


def by_item(checks):
    return {c.item: c for c in checks}


def test_everything_passes_on_healthy_fakes(tmp_path, monkeypatch):
    profile = lab_profile(tmp_path)
    make_camera, make_arm, apis = fakes(profile, monkeypatch, tmp_path)
    checks = run_checks(profile, make_camera, make_arm)
    failed = [(c.item, c.detail) for c in checks if c.ok is not True]
    assert failed == []
    items = by_item(checks)
    assert "30.0 fps" in items["camera streaming"].detail
    assert "v2.6.0" in items["firmware version"].detail
    assert items["state reports"].ok is True
    assert "ms on tcp/127.0.0.1" in items["e-stop over Zenoh"].detail
    assert "1.0 days old" in items["calibration"].detail
    assert apis[0].names()[-1] == "disconnect"  # the doctor closes what it opened
    console = Console(record=True, width=200)
    render(checks, console)
    assert "PASS" in console.export_text()


def test_each_fault_fails_its_item_with_a_hint(tmp_path, monkeypatch):
    profile = lab_profile(tmp_path, age_days=45, mode="eye_in_hand")

    def broken(api):
        api.warn_code = 11
        original = api.set_fence_mode
        api.set_fence_mode = lambda on: (original(False), 0)[1]  # controller accepts but does not apply

    make_camera, make_arm, _ = fakes(profile, monkeypatch, tmp_path, period_us=2 * PERIOD_US, setup_api=broken)
    items = by_item(run_checks(profile, make_camera, make_arm, zenoh=False))
    assert items["camera streaming"].ok is False and "15.0 fps" in items["camera streaming"].detail
    assert "USB 3" in items["camera streaming"].hint
    assert items["controller safety settings"].ok is False
    assert "fence" in items["controller safety settings"].detail
    assert items["calibration"].ok is False and "45 days old" in items["calibration"].detail
    assert "wants eye_to_hand" in items["calibration"].detail
    assert items["calibration"].hint.startswith("recalibrate")
    assert items["arm reachable"].ok is True


def test_silent_state_reports_fail(tmp_path, monkeypatch):
    profile = lab_profile(tmp_path)
    make_camera, make_arm, _ = fakes(profile, monkeypatch, tmp_path, setup_api=lambda api: setattr(api, "report_hz", 0))
    items = by_item(run_checks(profile, make_camera, make_arm, zenoh=False))
    assert items["state reports"].ok is False and "0 Hz" in items["state reports"].detail
    assert "30003" in items["state reports"].hint


def test_unreachable_devices_fail_every_dependent_item(tmp_path, monkeypatch):
    profile = lab_profile(tmp_path)
    _make_camera, make_arm, _ = fakes(
        profile, monkeypatch, tmp_path, setup_api=lambda api: setattr(api, "refuse_connect", True)
    )
    sdk_less = FemtoBolt(profile.camera, FakeOrbbecSDK(serials=()))
    items = by_item(run_checks(profile, lambda: sdk_less, make_arm, zenoh=False))
    for item in ("camera found", "camera streaming", "intrinsics sane", "arm reachable", "mode and state"):
        assert items[item].ok is False, item
    assert "ping" in items["arm reachable"].hint
    assert "no Orbbec camera" in items["camera found"].detail


def test_doctor_on_the_sim_passes_and_returns_zero():
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    profile = load_profile("configs/sim.yaml", {"runtime": {"zenoh": {"endpoint": endpoint}}})
    console = Console(record=True, width=200)
    assert run_doctor(profile, console) == 0
    text = console.export_text()
    assert "all checks passed" in text and f"on {endpoint}" in text and "simulated arm" in text


def test_packages_are_checked_against_the_pins(tmp_path):
    profile = lab_profile(tmp_path)
    pins = pinned_versions()
    assert pins["xarm-python-sdk"] == "1.18.4" and pins["pyorbbecsdk2"] == "2.1.2"
    (ok,) = check_packages(profile, pins)
    assert ok.ok is True and "xarm-python-sdk 1.18.4" in ok.detail
    (bad,) = check_packages(profile, {**pins, "mujoco": "0.0.1"})
    assert bad.ok is False and "0.0.1 pinned" in bad.detail and "setup.sh" in bad.hint
