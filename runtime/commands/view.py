"""`goalvla view RUN_DIR`: open a run's run.rrd in Rerun's viewer, the native one on a desktop, the web viewer
(served on the loopback, for a browser on this machine or through an SSH tunnel) when there is no display.

The viewer is the `rerun` program that rerun-sdk installs (the rerun_cli package's binary, started directly so
that stopping it stops the server). Its usage analytics are turned off first (`rerun analytics disable`): the
runtime's tools talk to the loopback only.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

RRD = "run.rrd"
Viewer = Literal["native", "web"]


class ViewError(RuntimeError):
    """The run folder has nothing to view, or the viewer cannot be started."""


@dataclass(frozen=True)
class ViewPlan:
    viewer: Viewer
    command: list[str]
    url: str | None  # the web viewer's address


def rerun_program() -> str:
    """The viewer binary rerun-sdk ships."""
    import rerun_cli

    program = Path(rerun_cli.__file__).parent / "rerun"
    if not program.is_file():
        raise ViewError(f"the Rerun viewer is missing ({program}): reinstall rerun-sdk (setup.sh)")
    return str(program)


def has_display(env: Mapping[str, str]) -> bool:
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


def recording_of(run_dir: Path) -> Path:
    """run_dir/run.rrd, or a ViewError that says why there is none."""
    if not run_dir.is_dir():
        raise ViewError(f"{run_dir} is not a run folder")
    rrd = run_dir / RRD
    if not rrd.is_file():
        why = "the run predates recordings or runtime.rerun_recording was off"
        raise ViewError(f"{run_dir} holds no {RRD} ({why}); report.html shows the run")
    return rrd


def plan_view(
    run_dir: Path,
    env: Mapping[str, str],
    viewer: Viewer | None = None,
    bind: str = "127.0.0.1",
    web_port: int = 9090,
    grpc_port: int = 9876,
) -> ViewPlan:
    """Which viewer, and the command that starts it: native with a display, web (on `bind`) without one."""
    rrd = recording_of(run_dir)
    chosen: Viewer = viewer or ("native" if has_display(env) else "web")
    rerun = [rerun_program()]
    if chosen == "native":
        return ViewPlan("native", [*rerun, str(rrd)], None)
    command = [*rerun, str(rrd), "--serve-web", "--bind", bind, "--port", str(grpc_port)]
    command += ["--web-viewer-port", str(web_port)]
    host = f"[{bind}]" if ":" in bind else bind
    url = f"http://{host}:{web_port}/?url=rerun%2Bhttp%3A%2F%2F{host}%3A{grpc_port}%2Fproxy"
    return ViewPlan("web", command, url)


def disable_analytics(env: Mapping[str, str]) -> None:
    subprocess.run([rerun_program(), "analytics", "disable"], env=dict(env), capture_output=True, check=False)


def view(plan: ViewPlan, env: Mapping[str, str], say) -> int:
    """Run the viewer until it is closed (native) or Ctrl-C (web); its exit code."""
    disable_analytics(env)
    if plan.url is not None:
        say(f"web viewer on {plan.url} (Ctrl-C stops it)")
    try:
        return subprocess.run(plan.command, env=dict(env), check=False).returncode
    except KeyboardInterrupt:
        return 0
    except OSError as e:
        raise ViewError(f"could not start the Rerun viewer: {e}") from e


def environment() -> dict[str, str]:
    return dict(os.environ)
