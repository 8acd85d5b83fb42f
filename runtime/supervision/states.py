"""The run's state machine: the only place that decides which state follows which.

Stages run in order; FAILED (with a reason) and ESTOPPED are reachable from every state. The one way back is the
second look before moving (RECHECKING): when the scene changed since the planning capture, the run goes back to
REASONING (something other than the target moved) or PLANNING (the target alone moved, its motion re-based).
ESTOPPED is latched: nothing but an explicit `reset()` leaves it, so a stage thread that was mid-way when the stop
came cannot advance the run afterwards. Every transition is handed to the listeners (publisher, recorder, progress
display).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from runtime.config import StateBudgets


class State(StrEnum):
    IDLE = "IDLE"
    CAPTURING = "CAPTURING"
    REASONING = "REASONING"
    GROUNDING = "GROUNDING"
    PLANNING = "PLANNING"
    AWAITING_CONFIRM = "AWAITING_CONFIRM"
    RECHECKING = "RECHECKING"
    EXECUTING = "EXECUTING"
    VERIFYING = "VERIFYING"
    DONE = "DONE"
    FAILED = "FAILED"
    ESTOPPED = "ESTOPPED"


SEQUENCE = (
    State.IDLE,
    State.CAPTURING,
    State.REASONING,
    State.GROUNDING,
    State.PLANNING,
    State.AWAITING_CONFIRM,
    State.RECHECKING,
    State.EXECUTING,
    State.VERIFYING,
    State.DONE,
)
TERMINAL = frozenset({State.DONE, State.FAILED, State.ESTOPPED})
MOVING = frozenset({State.EXECUTING})
BACK = {State.RECHECKING: frozenset({State.REASONING, State.PLANNING})}  # the only transitions back


class TransitionError(RuntimeError):
    """A transition the machine does not allow (most often: the run was stopped meanwhile)."""

    def __init__(self, current: State, wanted: State, reason: str) -> None:
        super().__init__(f"cannot go from {current} to {wanted}" + (f" (state reason: {reason})" if reason else ""))
        self.current, self.wanted = current, wanted


@dataclass(frozen=True)
class Transition:
    previous: State
    state: State
    reason: str
    stamp_s: float  # wall clock (time.time) when it happened
    seconds_in_previous: float


def _budget(budgets: StateBudgets, state: State) -> float | None:
    return getattr(budgets, state.lower(), None)


class StateMachine:
    """Thread-safe: the run thread advances it, the supervisor and message callbacks may fail or stop it."""

    def __init__(self, budgets: StateBudgets, clock: Callable[[], float] = time.monotonic) -> None:
        self.budgets = budgets
        self._clock = clock
        self._lock = threading.RLock()
        self._state = State.IDLE
        self._reason = ""
        self._entered = clock()
        self._listeners: list[Callable[[Transition], None]] = []
        self.history: list[Transition] = []

    @property
    def state(self) -> State:
        return self._state

    @property
    def reason(self) -> str:
        return self._reason

    def add_listener(self, listener: Callable[[Transition], None]) -> None:
        with self._lock:
            self._listeners.append(listener)

    def remove_listener(self, listener: Callable[[Transition], None]) -> None:
        """Waits for a transition being handed out: a listener removed after a transition began still gets it."""
        with self._lock:
            self._listeners.remove(listener)

    def seconds_in_state(self) -> float:
        return self._clock() - self._entered

    def overrun(self) -> tuple[State, float, float] | None:
        """(state, seconds in it, budget) when the current state has used up its time budget, else None."""
        with self._lock:
            budget = _budget(self.budgets, self._state)
            spent = self.seconds_in_state()
            return (self._state, spent, budget) if budget is not None and spent > budget else None

    def _go(self, state: State, reason: str) -> Transition:
        now = self._clock()
        t = Transition(self._state, state, reason, time.time(), now - self._entered)
        self._state, self._reason, self._entered = state, reason, now
        self.history.append(t)
        for listener in tuple(self._listeners):
            listener(t)
        return t

    def advance(self, state: State, reason: str = "") -> Transition:
        """Next pipeline state; raises TransitionError unless `state` directly follows the current one."""
        with self._lock:
            current = self._state
            if current in TERMINAL and state == State.CAPTURING:
                if current == State.ESTOPPED:
                    raise TransitionError(current, state, self._reason)
                self._go(State.IDLE, "new run")
                current = State.IDLE
            if current in TERMINAL or SEQUENCE.index(state) != SEQUENCE.index(current) + 1:
                raise TransitionError(current, state, self._reason)
            return self._go(state, reason)

    def back(self, state: State, reason: str) -> Transition:
        """Back to an earlier pipeline state (BACK says which may be reached from where); TransitionError
        otherwise."""
        with self._lock:
            if state not in BACK.get(self._state, ()):
                raise TransitionError(self._state, state, self._reason)
            return self._go(state, reason)

    def fail(self, reason: str) -> bool:
        """Go to FAILED unless the run already ended (a stop or an earlier failure wins). True if it changed."""
        with self._lock:
            if self._state in TERMINAL:
                return False
            self._go(State.FAILED, reason)
            return True

    def estop(self, reason: str) -> bool:
        """Latch ESTOPPED from any state (a stop after the run ended still latches). True if it changed."""
        with self._lock:
            if self._state == State.ESTOPPED:
                return False
            self._go(State.ESTOPPED, reason)
            return True

    def reset(self, reason: str = "operator reset") -> None:
        """Back to IDLE from an ended run; the only way out of ESTOPPED. Refused while a run is in progress."""
        with self._lock:
            if self._state not in TERMINAL and self._state != State.IDLE:
                raise TransitionError(self._state, State.IDLE, "a run is in progress: abort it first")
            if self._state != State.IDLE:
                self._go(State.IDLE, reason)
