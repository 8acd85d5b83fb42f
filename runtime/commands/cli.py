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


def _writable(path: Path, what: str, folder: bool = False) -> None:
    from drivers.files import InputFileError, check_output_path

    try:
        check_output_path(path, what, folder)
    except InputFileError as e:
        _fail(str(e))


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
    from runtime.commands.capture import save_frame
    from runtime.devices import open_devices

    profile = _load(config)
    _writable(out, "the capture folder (--out)", folder=True)
    with open_devices(profile) as devices:
        frame = devices.capture()
    for path in save_frame(frame, out):
        typer.echo(f"wrote {path}")


@app.command()
def demo(
    config: ConfigOption = DEFAULT_CONFIG,
    out: Annotated[Path, typer.Option(help="folder for the captures")] = Path("out/demo"),
) -> None:
    """Move the simulated arm through a few poses and save a capture at each (sim profiles only)."""
    from runtime.commands.demo import DemoRefused, run_demo

    profile = _load(config)
    if profile.robot.kind != "sim":
        _fail("the demo only drives the simulated arm; use a sim profile")
    _writable(out, "the demo folder (--out)", folder=True)
    try:
        run_demo(profile, out)
    except DemoRefused as e:
        _fail(f"demo stopped: {e}")


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


calibrate_app = typer.Typer(
    help="Calibration: print the ChArUco board, run the hand-eye procedure.", no_args_is_help=True
)
app.add_typer(calibrate_app, name="calibrate")
BoardOption = Annotated[Path, typer.Option("--board", help="board YAML", exists=True, dir_okay=False)]
DEFAULT_BOARD = Path("configs/boards/charuco_8x6_30mm.yaml")


@calibrate_app.command("board")
def calibrate_board(
    out: Annotated[Path, typer.Option("--out", help="board.png or board.pdf")],
    board: BoardOption = DEFAULT_BOARD,
    dpi: Annotated[int, typer.Option(help="print resolution")] = 300,
) -> None:
    """Write the board as a PNG/PDF at true scale: print at 100 % (no fit-to-page), check a square with a ruler."""
    from calibration.board import BoardError, load_board, write_printable

    try:
        spec = load_board(board)
        width, height = write_printable(spec, out, dpi)
    except BoardError as e:
        _fail(str(e))
    w_mm, h_mm = (1000 * v for v in spec.size_m)
    typer.echo(
        f"wrote {out}: {width}x{height} px at {dpi} dpi; board {w_mm:.0f} x {h_mm:.0f} mm plus 10 mm margin, "
        f"squares {1000 * spec.square_length_m:.1f} mm. Print at 100 % scale and measure a square."
    )


@calibrate_app.command("hand-eye")
def calibrate_hand_eye(
    mode: Annotated[str, typer.Option(help="eye-to-hand (fixed camera) or eye-in-hand (camera on the flange)")],
    config: ConfigOption = DEFAULT_CONFIG,
    board: BoardOption = DEFAULT_BOARD,
    out: Annotated[Path | None, typer.Option(help="calibration YAML (default: calibration.file)")] = None,
    yes: Annotated[bool, typer.Option("--yes", help="move without asking")] = False,
) -> None:
    """Drive the arm through safe views of the board, solve hand-eye, report residuals, store a good result."""
    from rich.console import Console

    from calibration.board import BoardError, load_board
    from calibration.mover import CalibrationRefused
    from runtime.commands.calibrate import run_hand_eye

    modes = {"eye-to-hand": "eye_to_hand", "eye-in-hand": "eye_in_hand"}
    if mode not in modes:
        _fail(f"--mode must be one of {', '.join(modes)}, got {mode!r}")
    profile = _load(config)
    target = out or profile.calibration.file or Path(f"calibration/{modes[mode]}.yaml")
    _writable(target, "the calibration file")
    try:
        spec = load_board(board)
        code = run_hand_eye(
            profile,
            lambda overrides: _load(config, overrides),
            spec,
            modes[mode],
            target,
            (lambda _: True) if yes else (lambda question: typer.confirm(question, default=False)),
            Console(),
        )
    except (BoardError, CalibrationRefused) as e:
        _fail(str(e))
    raise typer.Exit(code)


@app.command()
def ground(
    config: ConfigOption = DEFAULT_CONFIG,
    scene_file: Annotated[Path, typer.Option("--scene-file", help="PAIR.npz (keys: see DESIGN.md)")] = ...,
    out: Annotated[Path, typer.Option(help="RESULT.json")] = ...,
) -> None:
    """Spatial grounding alone: the object's motion x_goal = R x_init + t (camera frame) from PAIR.npz.

    Exit 0 grounded, 1 refused (RESULT.json says why), 2 unusable input."""
    from runtime.commands.ground_command import ground_command

    raise typer.Exit(ground_command(_load(config), scene_file, out))


@app.command()
def run(
    config: ConfigOption = DEFAULT_CONFIG,
    instruction: Annotated[str | None, typer.Option(help="e.g. 'put the red block on the white plate'")] = None,
    scene: Annotated[str | None, typer.Option(help="sim scene name (sim profiles only)")] = None,
    seed: Annotated[int | None, typer.Option(help="sim scene seed (sim profiles only)")] = None,
    yes: Annotated[bool, typer.Option("--yes", help="approve the plan without asking; e-stop still works")] = False,
    record: Annotated[Path | None, typer.Option(help="run folder (default: runtime.runs_dir/<run id>)")] = None,
    serve: Annotated[bool, typer.Option("--serve", help="stay up and run instructions sent from the console")] = False,
    allow_unvalidated_goal: Annotated[
        bool,
        typer.Option("--allow-unvalidated-goal", help="operator override: use the last goal image none validated"),
    ] = False,
) -> None:
    """One supervised run: capture, reason, ground, plan, gate, confirm, execute, verify.

    Exit 0 only when verification finds the goal reached; 1 failed, 3 e-stopped, 2 unusable arguments."""
    from runtime.commands.launch import run_command
    from runtime.run.record import run_folder_problem

    if serve == (instruction is not None):
        _fail("give --instruction TEXT for one run, or --serve to take instructions from the console")
    if record is not None and (problem := run_folder_problem(record)) is not None:
        _fail(f"--record: {problem}")
    sim = {k: v for k, v in (("scene", scene), ("seed", seed)) if v is not None}
    overrides: dict = {"sim": sim} if sim else {}
    if allow_unvalidated_goal:
        overrides["pipeline"] = {"allow_unvalidated_goal": True}
    profile = _load(config, overrides or None)
    if sim and not profile.robot.simulated:
        _fail(f"--scene/--seed only apply to sim profiles; {config} drives robot.kind {profile.robot.kind!r}")
    _refuse_unstartable(profile, instruction)
    raise typer.Exit(run_command(profile, instruction, yes, record, serve))


def _refuse_unstartable(profile, instruction: str | None) -> None:
    """Exit 2 before any device starts: missing API keys, a sentence outside the offline grammar (when the offline
    VLM reads it), a sim scene that cannot be loaded or placed."""
    from pipeline.reasoning.factory import preflight
    from pipeline.reasoning.instruction import InstructionError, check_instruction

    problems = preflight(profile.pipeline)
    if instruction is not None and profile.pipeline.vlm == "offline":
        try:
            check_instruction(instruction)
        except InstructionError as e:
            problems.append(str(e))
    if profile.robot.kind == "sim":
        from drivers.sim.generate import check_scene
        from drivers.sim.scene import SceneError

        try:
            check_scene(profile.sim)
        except SceneError as e:
            problems.append(str(e))
    if problems:
        _fail("cannot start:\n  " + "\n  ".join("\n  ".join(p.splitlines()) for p in problems))


def _seeds(text: str) -> list[int]:
    """N (seeds 0..N-1, or from --seed-start) or A:B (seeds A..B-1)."""
    try:
        if ":" in text:
            a, b = (int(x) for x in text.split(":"))
            return list(range(a, b))
        return list(range(int(text)))
    except ValueError:
        _fail(f"--seeds: give a count N or a range A:B, got {text!r}")


@app.command("eval")
def eval_campaign(
    out: Annotated[Path, typer.Option(help="campaign folder (runs/, results.json/.md/.html); reused to resume")],
    config: ConfigOption = DEFAULT_CONFIG,
    tasks: Annotated[
        str, typer.Option(help="comma-separated: named tasks (tomato_pan, block_scale, ...), gen, gen-all")
    ] = "tomato_pan,block_scale,bottle_standup,close_lid",
    seeds: Annotated[str, typer.Option(help="N (seeds seed-start.. +N) or A:B")] = "10",
    seed_start: Annotated[int, typer.Option(help="first seed when --seeds is a count")] = 0,
    trials: Annotated[int, typer.Option(min=1, help="trials per seed")] = 1,
    workers: Annotated[int, typer.Option(min=1, help="runs at a time (processes here, or CPUs of --ray local)")] = 2,
    ray: Annotated[
        str | None, typer.Option("--ray", help="run on the Ray cluster at ADDRESS, or 'local' to start one here")
    ] = None,
    recording: Annotated[bool, typer.Option("--recording/--no-recording", help="run.rrd in each run")] = True,
    stepped: Annotated[
        bool,
        typer.Option(
            "--stepped",
            help="the simulated physics advanced by the executor's clock: a loaded machine cannot starve the "
            "simulated robot (wall times then say nothing of real time)",
        ),
    ] = False,
) -> None:
    """A campaign: every (task, seed, trial) a whole run with its own record; a results table like the paper's.

    Resumable: the same command skips the runs already done. Exit 0 when every run has a result (whatever it is),
    1 when some crashed (they run again on resume), 2 unusable arguments."""
    from rich.console import Console

    from runtime.campaign.campaign import CampaignError, CampaignSpec, run_campaign
    from runtime.campaign.pools import ProcessPool, RayPool

    profile = _load(config)
    if not profile.robot.simulated or profile.robot.kind != "sim":
        _fail(f"{config}: campaigns run on the simulator (robot.kind sim); it drives {profile.robot.kind!r}")
    seed_list = _seeds(seeds) if ":" in seeds else [seed_start + s for s in _seeds(seeds)]
    spec = CampaignSpec(
        name=out.resolve().name,
        config=str(config.resolve()),
        tasks=tuple(t.strip() for t in tasks.split(",") if t.strip()),
        seeds=tuple(seed_list),
        trials=trials,
        rerun_recording=recording,
        stepped=stepped,
    )
    try:
        spec.cases()
    except CampaignError as e:
        _fail(str(e))
    _writable(out, "the campaign folder (--out)", folder=True)
    pool = RayPool(ray, workers) if ray else ProcessPool(workers)
    try:
        outcome = run_campaign(spec, out, pool, Console())
    except CampaignError as e:
        _fail(str(e))
    finally:
        pool.close()
    raise typer.Exit(1 if outcome.errors else 0)


@app.command()
def view(
    run_dir: Annotated[Path, typer.Argument(help="a run folder (with run.rrd)")],
    web: Annotated[
        bool | None,
        typer.Option("--web/--native", help="force the web or the native viewer (default: native with a display)"),
    ] = None,
    bind: Annotated[str, typer.Option(help="web viewer address; keep the loopback unless you know why")] = "127.0.0.1",
    port: Annotated[int, typer.Option(help="web viewer HTTP port")] = 9090,
    grpc_port: Annotated[int, typer.Option(help="port the web viewer reads the recording from")] = 9876,
) -> None:
    """Open a run's Rerun recording: the native viewer, or the web viewer on the loopback without a display."""
    from runtime.commands.view import ViewError, environment, plan_view
    from runtime.commands.view import view as open_viewer

    env = environment()
    try:
        plan = plan_view(run_dir, env, None if web is None else ("web" if web else "native"), bind, port, grpc_port)
        raise typer.Exit(open_viewer(plan, env, typer.echo))
    except ViewError as e:
        _fail(str(e))


@app.command()
def estop(
    config: ConfigOption = DEFAULT_CONFIG,
    node: Annotated[str, typer.Option(help="this node's name in heartbeat/<node>")] = "estop-terminal",
) -> None:
    """Teleop e-stop: heartbeats at 20 Hz (the deadman); ANY KEY sends an e-stop, Ctrl-C sends one and quits."""
    from runtime.messaging.bus import Bus
    from runtime.supervision.estop import run_terminal_node

    profile = _load(config)
    cfg = profile.runtime
    with Bus(cfg.zenoh, cfg.robot_id, "connect") as bus:
        run_terminal_node(bus, node, cfg.heartbeat_rate_hz, typer.echo)


@app.command()
def reset(
    config: ConfigOption = DEFAULT_CONFIG,
    yes: Annotated[bool, typer.Option("--yes", help="the cell has been checked; do not ask")] = False,
) -> None:
    """Release a lasting e-stop latch (runtime.estop_latch_file) after someone checked the cell.

    Exit 0 released or nothing latched, 1 not confirmed, 2 no latch file configured."""
    from runtime.supervision.estop_latch import EStopLatch

    path = _load(config).runtime.estop_latch_file
    if path is None:
        _fail(f"{config}: runtime.estop_latch_file is not set; an e-stop lasts only as long as its runtime")
    latch = EStopLatch(path)
    latched = latch.engaged()
    if latched is None:
        typer.echo(f"no e-stop latched ({path})")
        raise typer.Exit(0)
    typer.echo(latched.describe())
    if not (yes or typer.confirm("Has someone checked the cell and is it safe to run again?", default=False)):
        typer.echo("still latched")
        raise typer.Exit(1)
    latch.release("goalvla reset")
    typer.echo("released: the next run may start")


@app.command()
def console(
    config: ConfigOption = DEFAULT_CONFIG,
    port: Annotated[int, typer.Option(help="HTTP port of the operator page")] = 8080,
    host: Annotated[str, typer.Option(help="HTTP address; keep the loopback default unless behind TLS")] = "127.0.0.1",
    allow_host: Annotated[
        list[str] | None,
        typer.Option(help="a host name the page may be opened under besides the address itself (repeatable)"),
    ] = None,
) -> None:
    """Operator console: a web page (http://HOST:PORT) with live status, images, plan, Run/Confirm/Abort/E-STOP."""
    from runtime.messaging.console.server import serve_console

    profile = _load(config)
    serve_console(profile.runtime, host, port, frozenset(allow_host or ()))


@app.command()
def doctor(config: ConfigOption = DEFAULT_CONFIG) -> None:
    """Bring-up checklist (packages, camera, arm, controller safety, e-stop over Zenoh, calibration); exit 1 on a
    failure."""
    from rich.console import Console

    from runtime.commands.doctor import run_doctor

    raise typer.Exit(run_doctor(_load(config), Console()))


@app.command()
def emulator(
    config: ConfigOption = Path("configs/emulated.yaml"),
    address: Annotated[
        str | None, typer.Option(help="loopback address to listen on; default robot.ip of an emulated profile")
    ] = None,
) -> None:
    """The xArm 7 controller emulator over the profile's MuJoCo scene: TCP 502 and 30003 on a loopback address,
    for any xarm-python-sdk client, until Ctrl-C. (`goalvla run` with an emulated profile starts its own.)"""
    import threading

    from drivers.xarm7.emulator import EmulatorBindError
    from drivers.xarm7.emulator.cell import serve

    profile = _load(config)
    if address is None and not profile.robot.emulated:
        _fail(f"{config} is not an emulated profile (robot.emulated): give --address 127.0.0.N")
    try:
        serve(
            profile.sim,
            profile.camera,
            address or str(profile.robot.ip),
            profile.robot.control_rate_hz,
            typer.echo,
            threading.Event(),
        )
    except (EmulatorBindError, ValueError) as e:
        _fail(str(e))


if __name__ == "__main__":
    app()
