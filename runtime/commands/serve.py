"""Console-driven operation (`goalvla run --serve`): run the instructions and resets that arrive on `command`,
and keep the console's camera view fresh between runs. Abort and e-stop never queue here: the supervisor acts
on them as they arrive."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from runtime.run.runner import RunResult, Runtime
from runtime.supervision.states import State, TransitionError

PREVIEW_PERIOD_S = 2.0  # camera frames for the console between runs


def serve(rt: Runtime, stop: threading.Event, on_result: Callable[[RunResult], None] | None = None) -> None:
    """Until `stop` is set."""
    next_preview = 0.0
    while not stop.is_set():
        if not rt.supervisor.command_ready.wait(0.05):
            if time.monotonic() >= next_preview:
                next_preview = time.monotonic() + PREVIEW_PERIOD_S
                rt.preview()
            continue
        cmd = rt.supervisor.next_command()
        if cmd is None:
            continue
        try:
            if cmd.action == "reset":
                rt.reset(cmd.source or "console")
            elif rt.machine.state == State.ESTOPPED:
                rt.status.event("run refused: ESTOPPED, press Reset first", "warning")
            else:
                result = rt.run(cmd.instruction)
                if on_result is not None:
                    on_result(result)
        except TransitionError as e:
            rt.status.event(f"{cmd.action} refused: {e}", "warning")
