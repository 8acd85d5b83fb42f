"""`goalvla run`: open the devices, start the runtime node, run one instruction (or serve the console's) and
map the outcome to the exit code: 0 verified success, 1 failed, 3 e-stopped, 2 not startable (missing API keys)."""

from __future__ import annotations

import sys
import threading
from pathlib import Path

from rich.console import Console

from pipeline.reasoning.factory import preflight
from runtime.commands.progress import ProgressView
from runtime.commands.serve import serve
from runtime.config import Profile
from runtime.devices import missing_device_packages, open_devices
from runtime.messaging.messages import PlanSummary
from runtime.run.runner import Runtime
from runtime.run.stages import PipelineStages
from runtime.sim_truth.listener import SimTruth
from runtime.supervision.states import State

EXIT_CODES = {State.DONE: 0, State.FAILED: 1, State.ESTOPPED: 3}


def describe_plan(plan: PlanSummary) -> str:
    peak = max(plan.peak_joint_speed_rad_s, default=0.0)
    clearance = "n/a" if plan.min_clearance_m is None else f">= {plan.min_clearance_m * 1000:.0f} mm"
    return (
        f"plan {plan.plan_id}: {plan.mode or 'motion'} for '{plan.instruction}', {plan.duration_s:.1f} s, "
        f"peak joint speed {peak:.2f} rad/s, min clearance {clearance}, gate {'passed' if plan.gate_ok else 'FAILED'}"
    )


def run_command(profile: Profile, instruction: str | None, yes: bool, record: Path | None, serve: bool) -> int:
    console = Console(stderr=True)
    confirm = "yes" if yes else ("prompt" if sys.stdin.isatty() and not serve else "console")

    def prompt(plan: PlanSummary) -> bool:
        answer = console.input(f"\n[bold]{describe_plan(plan)}[/bold]\nExecute this plan? [y/N] ")
        return answer.strip().lower() in ("y", "yes")

    problems = preflight(profile.pipeline) + missing_device_packages(profile)
    if problems:  # before any device moves: a missing key or package must not surface in the middle of a run
        console.print("[red]cannot start:[/red]\n  " + "\n  ".join(problems))
        return 2
    with open_devices(profile) as devices:
        stages = PipelineStages(listeners=[SimTruth()] if devices.world is not None else [])  # sim: its truth too
        with Runtime(profile, devices, stages, confirm, prompt) as rt:
            cfg = profile.runtime
            console.print(
                f"runtime node on {cfg.zenoh.endpoint}, keys goalvla/{cfg.robot_id}/..., e-stop: {cfg.estop_node}"
            )
            if serve:
                return _serve(rt, console)
            with ProgressView(console) as view:
                rt.machine.add_listener(view.on_transition)
                if cfg.estop_node == "external":
                    view.note("execution needs a running `goalvla estop` node (deadman)")
                if confirm == "console":
                    view.note("confirm the plan in `goalvla console`")
                result = rt.run(instruction or "", record)
            console.print(f"\nrun record: {result.run_dir / 'summary.json'}  report: {result.run_dir / 'report.html'}")
            return EXIT_CODES.get(result.status, 1)


def _serve(rt: Runtime, console: Console) -> int:
    stop = threading.Event()
    console.print("serving instructions from the console; Ctrl-C stops the arm and quits")
    try:
        serve(rt, stop, lambda r: console.print(f"{r.status.value}: {r.reason}  ({r.run_dir})"))
    except KeyboardInterrupt:
        rt.supervisor.estop("runtime interrupted (Ctrl-C)")
    return 0
