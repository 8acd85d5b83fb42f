"""How the simulator judges whether a run really did its job, beside the run's own verdict (never used by it).

A rule reads the case and the run's summary (its `sim_truth` section, runtime.sim_truth.listener) and answers
True (done), False (not done) or None (cannot tell). The simulator's truth is taken at the capture that verifies:
a run that ended before executing never moved anything, so it is not done; one that ended while executing has no
truth (None). The tolerances are the verification's own. A place is judged by where the object's centre ended (it
may leave it turned: a ball dropped into a bowl); a turn or a stand-up also by how far its shape is turned from
the goal's turn, up to the turns its shape does not show; a push by not having tipped the object (a twist along
the way is no matter). Tasks with their own truth (the fraction of screws in a dustpan, an object lifted clear)
use `task_done`, which reads the listener's task truth.
"""

from __future__ import annotations

from collections.abc import Callable

from runtime.campaign.cases import Case
from runtime.run.summary import RunSummary

POSITION_TOL_M = 0.03  # the verification's own tolerances (runtime.verify_position_tol_m / _rotation_tol_deg)
TURN_TOL_DEG = 15.0
LID_SHUT_DEG = 15.0

Rule = Callable[[Case, RunSummary], bool | None]


def _without_truth(summary: RunSummary) -> bool | None:
    """No truth was taken: not done when the arm never moved, unknown when the run stopped while it moved."""
    moved = any(t.state == "EXECUTING" for t in summary.transitions)
    return None if moved else False


def goal_error(case: Case, summary: RunSummary) -> bool | None:
    """The object that moved most is the case's target and its centre ended within POSITION_TOL_M of where the
    goal motion puts it."""
    truth = summary.sim_truth
    if truth is None:
        return _without_truth(summary)
    if truth.target_goal_error_m is None:
        return False
    right_object = case.target is None or truth.target == case.target
    return bool(right_object and truth.target_goal_error_m <= POSITION_TOL_M)


def goal_turn(case: Case, summary: RunSummary) -> bool | None:
    """goal_error, and the target's shape within TURN_TOL_DEG of the goal's turn (a rotation, a stand-up)."""
    placed = goal_error(case, summary)
    if not placed:
        return placed
    turn = summary.sim_truth.target_turn_error_deg
    return turn is not None and turn <= TURN_TOL_DEG


def goal_upright(case: Case, summary: RunSummary) -> bool | None:
    """goal_error, and the target tipped no more than TURN_TOL_DEG from the goal's pose (a push)."""
    placed = goal_error(case, summary)
    if not placed:
        return placed
    tilt = summary.sim_truth.target_tilt_error_deg
    return tilt is not None and tilt <= TURN_TOL_DEG


def stood_up(case: Case, summary: RunSummary) -> bool | None:
    """goal_turn, and standing the right way up by the task's own truth (a bottle on its neck is not stood up,
    though a registration that turned it end for end makes that its goal)."""
    placed = goal_turn(case, summary)
    if not placed:
        return placed
    task = summary.sim_truth.task
    return task is not None and task.done


def hinge_shut(case: Case, summary: RunSummary) -> bool | None:
    """The target's lid hinge ended within LID_SHUT_DEG of shut."""
    truth = summary.sim_truth
    if truth is None:
        return _without_truth(summary)
    name = f"{case.target}_hinge" if case.target else None
    angles = [a for joint, a in truth.hinge_deg.items() if name is None or joint == name]
    return bool(angles) and max(abs(a) for a in angles) <= LID_SHUT_DEG


def task_done(case: Case, summary: RunSummary) -> bool | None:
    """The task's own truth (runtime.sim_truth.tasks): a sweep's parts in the dustpan, an object lifted clear, a
    support left empty."""
    truth = summary.sim_truth
    if truth is None:
        return _without_truth(summary)
    return bool(truth.task is not None and truth.task.done)


RULES: dict[str, Rule] = {
    "goal_error": goal_error,
    "goal_turn": goal_turn,
    "goal_upright": goal_upright,
    "stood_up": stood_up,
    "hinge_shut": hinge_shut,
    "task_done": task_done,
}


def judge(case: Case, summary: RunSummary) -> bool | None:
    try:
        rule = RULES[case.truth]
    except KeyError:
        raise ValueError(f"case {case.id}: unknown truth rule {case.truth!r}; known: {', '.join(RULES)}") from None
    return rule(case, summary)
