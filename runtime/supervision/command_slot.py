"""The operator's run and reset requests for a serving runtime: at most one waiting, none while a run is under way.

A request that cannot be carried out now is refused with the reason, never queued: a Run pressed during a run
(or twice) must not start a run by itself later, after an Abort, and a flood of requests costs nothing. Abort
and e-stop never come here: the supervisor acts on them as they arrive.
"""

from __future__ import annotations

import threading

from runtime.messaging.messages import Command
from runtime.supervision.states import TERMINAL, State


class CommandSlot:
    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._waiting: Command | None = None
        self._busy = False  # a request was taken and its run has not ended yet
        self.ready = threading.Event()  # a request is waiting

    def offer(self, cmd: Command, state: State) -> str | None:
        """Take `cmd` (run or reset) to be carried out next: None, or the reason it is refused."""
        what = cmd.action
        if state not in TERMINAL and state != State.IDLE:
            return f"{what} refused: a run is in progress ({state}); abort it first"
        if what == "run" and state == State.ESTOPPED:
            return "run refused: ESTOPPED; check the cell, then press Reset"
        if what == "run" and not cmd.instruction.strip():
            return "run refused: no instruction"
        with self._lock:
            if self._busy or self._waiting is not None:
                return f"{what} refused: the previous request is still being carried out"
            self._waiting = cmd
            self.ready.set()
        return None

    def take(self) -> Command | None:
        """The waiting request, now being carried out (until `done()` or the run's end)."""
        with self._lock:
            cmd, self._waiting = self._waiting, None
            self.ready.clear()
            self._busy = self._busy or cmd is not None
            return cmd

    def done(self) -> None:
        """The taken request was carried out (its run ended, or it was a reset)."""
        with self._lock:
            self._busy = False
