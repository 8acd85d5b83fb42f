"""Console-driven operation (`goalvla run --serve`): run the instructions and resets that arrive on `command`,
and keep the console's camera view fresh between runs. The supervisor's command slot holds at most one request
and refuses the rest (runtime.supervision.command_slot); abort and e-stop never wait here: the supervisor acts
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
    slot = rt.supervisor.commands
    while not stop.is_set():
        if not slot.ready.wait(0.05):
            if time.monotonic() >= next_preview:
                next_preview = time.monotonic() + PREVIEW_PERIOD_S
                rt.preview()
            continue
        cmd = slot.take()
        if cmd is None:
            continue
        try:
            if cmd.action == "reset":
                rt.reset(cmd.source or "console")
            elif rt.machine.state == State.ESTOPPED:
                rt.supervisor.notice("run refused: ESTOPPED; check the cell, then press Reset")
            else:
                result = rt.run(cmd.instruction)
                if on_result is not None:
                    on_result(result)
        except (TransitionError, OSError) as e:  # OSError: the run folder could not be made
            rt.supervisor.notice(f"{cmd.action} refused: {e}")
        finally:
            slot.done()
