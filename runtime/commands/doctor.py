"""`goalvla doctor`: the bring-up checklist. Each item passes or fails with a hint; a failed prerequisite turns
the items that need it into failures too (nothing is assumed). Exit code 1 if any item fails.

Items (doctor_checks.py): packages, camera streaming and rate, intrinsics, arm reachable, firmware,
controller errors/warnings, mode/state, controller safety settings, e-stop round trip over Zenoh, calibration
present and recent.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from runtime.commands.doctor_checks import (
    Check,
    check_arm,
    check_calibration,
    check_camera,
    check_estop_round_trip,
    check_packages,
)
from runtime.config import Profile


def run_checks(
    profile: Profile, make_camera: Callable[[], Any], make_arm: Callable[[], Any], zenoh: bool = True
) -> list[Check]:
    """Every item in order; devices are closed afterwards whatever happened."""
    checks = check_packages(profile)
    camera, arm = make_camera(), make_arm()
    try:
        checks += check_camera(camera, profile.camera.fps, simulated=profile.camera.kind == "sim")
        checks += check_arm(arm)
    finally:
        for device in (arm, camera):
            try:
                device.close()
            except Exception as e:
                checks.append(Check("close", False, f"{type(device).__name__}.close(): {e}"))
    if zenoh:
        checks.append(check_estop_round_trip(profile))
    checks.append(check_calibration(profile))
    return checks


def render(checks: list[Check], console: Console) -> None:
    table = Table(title="goalvla doctor")
    for column in ("", "item", "detail", "how to fix"):
        table.add_column(column, overflow="fold")
    marks = {True: "[green]PASS[/green]", False: "[red]FAIL[/red]", None: "[dim]n/a[/dim]"}
    for c in checks:
        table.add_row(marks[c.ok], c.item, escape(c.detail), escape(c.hint))  # details hold [lists], not markup
    console.print(table)


def device_factories(profile: Profile) -> tuple[Callable[[], Any], Callable[[], Any], Callable[[], None]]:
    """Camera and arm of the profile, unconnected (the checks connect them and report how that went), and a
    cleanup for what the factories started."""
    if profile.robot.kind == "sim" and profile.camera.kind == "sim":
        from drivers.sim import SimArm, SimCamera, SimWorld

        world = SimWorld(profile.sim, profile.camera)
        if profile.sim.realtime:
            world.start()
        return (
            lambda: SimCamera(world, seed=profile.sim.seed),
            lambda: SimArm(world, profile.robot.control_rate_hz),
            world.stop,
        )
    if profile.robot.emulated:
        from runtime.devices import _emulated_cell

        cell = _emulated_cell(profile)
        return (lambda: cell.camera), (lambda: cell.arm), cell.stop
    from runtime.devices import _hardware_devices

    camera, arm, _, _ = _hardware_devices(profile)
    return (lambda: camera), (lambda: arm), (lambda: None)


def run_doctor(profile: Profile, console: Console) -> int:
    make_camera, make_arm, cleanup = device_factories(profile)
    try:
        checks = run_checks(profile, make_camera, make_arm)
    finally:
        cleanup()
    render(checks, console)
    failed = [c.item for c in checks if c.ok is False]
    console.print(f"[red]{len(failed)} failed: {', '.join(failed)}" if failed else "[green]all checks passed")
    return 1 if failed else 0
