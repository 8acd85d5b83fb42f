"""The `goalvla` command line. Each command parses its arguments and hands over to the module that does the
work; heavy imports happen inside the commands so `goalvla --help` stays fast."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

app = typer.Typer(
    name="goalvla",
    help="Goal-VLA deployment runtime: xArm 7 + Femto Bolt, or their MuJoCo twin (configs/sim.yaml).",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)

ConfigOption = Annotated[Path, typer.Option("--config", "-c", help="profile YAML", exists=True, dir_okay=False)]
DEFAULT_CONFIG = Path("configs/sim.yaml")


def _fail(message: str, code: int = 2) -> None:
    typer.secho(f"error: {message}", fg=typer.colors.RED, err=True)
    raise typer.Exit(code)


def _load(config: Path, overrides: dict | None = None):
    from runtime.config import ConfigError, load_profile

    try:
        return load_profile(config, overrides)
    except ConfigError as e:
        _fail(str(e))


@app.command()
def capture(
    config: ConfigOption = DEFAULT_CONFIG,
    out: Annotated[Path, typer.Option(help="folder for rgb.png, depth.png, frame.npz")] = Path("out/capture"),
) -> None:
    """Capture one RGB-D frame (with T_base_camera from the calibration) and save it."""
    from runtime.capture import save_frame
    from runtime.devices import open_devices

    profile = _load(config)
    with open_devices(profile) as devices:
        frame = devices.camera.read().with_extrinsics(devices.T_base_camera)
    for path in save_frame(frame, out):
        typer.echo(f"wrote {path}")


@app.command()
def demo(
    config: ConfigOption = DEFAULT_CONFIG,
    out: Annotated[Path, typer.Option(help="folder for the captures")] = Path("out/demo"),
) -> None:
    """Move the simulated arm through a few poses and save a capture at each (sim profiles only)."""
    from runtime.demo import run_demo

    profile = _load(config)
    if profile.robot.kind != "sim":
        _fail("the demo only drives the simulated arm; use a sim profile")
    run_demo(profile, out)


@app.command("check-trajectory")
def check_trajectory(
    trajectory: Annotated[Path, typer.Option("--trajectory", "-t", help="TRAJ.json: joint_names, dt, positions")],
    config: ConfigOption = DEFAULT_CONFIG,
    world: Annotated[Path | None, typer.Option("--world", "-w", help="WORLD.json: boxes, spheres, ...")] = None,
) -> None:
    """The safety gate alone: print a JSON report; exit 0 valid, 3 violations, 2 unusable input."""
    import json

    from safety.check_files import InputError, check_files

    profile = _load(config)
    try:
        report = check_files(profile.safety, trajectory, world)
    except InputError as e:
        _fail(str(e))
    typer.echo(json.dumps(report.to_dict(), indent=2))
    raise typer.Exit(0 if report.ok else 3)


if __name__ == "__main__":
    app()
