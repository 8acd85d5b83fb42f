"""The state machine: order, FAILED and ESTOPPED from anywhere, the latch, budgets, listeners."""

from __future__ import annotations

import pytest

from runtime.config import StateBudgets
from runtime.supervision.states import SEQUENCE, State, StateMachine, TransitionError


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_full_sequence_is_recorded_with_timings():
    clock = Clock()
    sm = StateMachine(StateBudgets(), clock)
    seen = []
    sm.add_listener(seen.append)
    for state in SEQUENCE[1:]:
        clock.t += 1.5
        sm.advance(state)
    assert sm.state == State.DONE
    assert [t.state for t in seen] == list(SEQUENCE[1:])
    assert all(t.seconds_in_previous == pytest.approx(1.5) for t in seen)


def test_skipping_a_stage_is_refused():
    sm = StateMachine(StateBudgets())
    sm.advance(State.CAPTURING)
    with pytest.raises(TransitionError, match="CAPTURING to PLANNING"):
        sm.advance(State.PLANNING)


@pytest.mark.parametrize("upto", range(1, len(SEQUENCE) - 1))
def test_estop_from_every_state_is_latched(upto):
    sm = StateMachine(StateBudgets())
    for state in SEQUENCE[1 : upto + 1]:
        sm.advance(state)
    assert sm.estop("button")
    assert sm.state == State.ESTOPPED and sm.reason == "button"
    with pytest.raises(TransitionError):  # a stage finishing late cannot move on
        sm.advance(SEQUENCE[upto + 1])
    with pytest.raises(TransitionError):  # nor can a new run start
        sm.advance(State.CAPTURING)
    assert not sm.fail("late failure") and sm.state == State.ESTOPPED
    sm.reset()
    assert sm.state == State.IDLE
    sm.advance(State.CAPTURING)


def test_only_the_second_look_goes_back_and_only_to_reasoning_or_planning():
    sm = StateMachine(StateBudgets())
    for state in SEQUENCE[1 : SEQUENCE.index(State.RECHECKING)]:
        sm.advance(state)
        with pytest.raises(TransitionError):  # no way back before the second look
            sm.back(State.REASONING, "changed")
    sm.advance(State.RECHECKING)
    with pytest.raises(TransitionError):
        sm.back(State.GROUNDING, "changed")
    sm.back(State.PLANNING, "the target moved")
    assert sm.state == State.PLANNING and sm.reason == "the target moved"
    sm.advance(State.AWAITING_CONFIRM)
    sm.advance(State.RECHECKING)
    sm.back(State.REASONING, "a neighbour moved")
    sm.advance(State.GROUNDING)
    assert sm.estop("button") and sm.state == State.ESTOPPED
    with pytest.raises(TransitionError):
        sm.back(State.REASONING, "late")


def test_fail_keeps_the_first_reason_and_a_new_run_may_follow():
    sm = StateMachine(StateBudgets())
    sm.advance(State.CAPTURING)
    assert sm.fail("camera timeout after 1.0 s")
    assert not sm.fail("second reason")
    assert sm.reason == "camera timeout after 1.0 s"
    sm.advance(State.CAPTURING)  # FAILED -> IDLE -> CAPTURING
    assert [t.state for t in sm.history][-2:] == [State.IDLE, State.CAPTURING]


def test_reset_refused_mid_run():
    sm = StateMachine(StateBudgets())
    sm.advance(State.CAPTURING)
    with pytest.raises(TransitionError, match="abort it first"):
        sm.reset()


def test_budget_overrun_is_reported_per_state():
    clock = Clock()
    sm = StateMachine(StateBudgets(capturing=2.0), clock)
    sm.advance(State.CAPTURING)
    clock.t = 1.9
    assert sm.overrun() is None
    clock.t = 2.1
    state, spent, budget = sm.overrun()
    assert (state, budget) == (State.CAPTURING, 2.0) and spent == pytest.approx(2.1)
