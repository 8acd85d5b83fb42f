"""A live terminal view of a run: every state with its time, the current one spinning, the reason on failure."""

from __future__ import annotations

import threading
import time

from rich.console import Console, Group
from rich.live import Live
from rich.spinner import Spinner
from rich.table import Table
from rich.text import Text

from runtime.supervision.states import SEQUENCE, State, Transition

STYLE = {State.DONE: "bold green", State.FAILED: "bold yellow", State.ESTOPPED: "bold red"}


class ProgressView:
    def __init__(self, console: Console | None = None) -> None:
        self.console = console or Console(stderr=True)
        self._lock = threading.Lock()
        self._seconds: dict[State, float] = {}
        self._failed: State | None = None
        self._current: State = State.IDLE
        self._entered = time.monotonic()
        self._end: Transition | None = None
        self._notes: list[str] = []
        self._live = Live(self._render(), console=self.console, refresh_per_second=8, transient=False)

    def __enter__(self) -> ProgressView:
        self._live.__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        self._live.update(self._render())
        self._live.__exit__(None, None, None)

    def on_transition(self, t: Transition) -> None:
        with self._lock:
            if t.previous in SEQUENCE:
                self._seconds[t.previous] = t.seconds_in_previous
            self._current, self._entered = t.state, time.monotonic()
            if t.state in STYLE:
                self._end = t
                if t.state != State.DONE:
                    self._failed = t.previous
        self._live.update(self._render())

    def note(self, text: str) -> None:
        with self._lock:
            self._notes.append(text)
        self._live.update(self._render())

    def _render(self) -> Group:
        table = Table.grid(padding=(0, 2))
        for state in SEQUENCE[1:-1]:
            if state == self._current and self._end is None:
                mark = Spinner("dots", style="cyan")
                secs = Text(f"{time.monotonic() - self._entered:5.1f} s", style="cyan")
            elif state == self._failed:
                mark, secs = Text("✗", style=STYLE[self._end.state]), Text(f"{self._seconds.get(state, 0):5.1f} s")
            elif state in self._seconds:
                mark, secs = Text("✓", style="green"), Text(f"{self._seconds[state]:5.1f} s")
            else:
                mark, secs = Text("·", style="dim"), Text("")
            table.add_row(mark, Text(state.value), secs)
        parts: list = [table, *(Text(n, style="dim") for n in self._notes[-4:])]
        if self._end is not None:
            parts.append(Text(f"{self._end.state.value}: {self._end.reason}", style=STYLE[self._end.state]))
        return Group(*parts)
