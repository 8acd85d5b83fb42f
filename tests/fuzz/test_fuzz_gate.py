"""The trajectory gate under absurd trajectories and configs: it answers every one within bounded time and
memory, refuses what breaks a limit (found without expanding an absurd jump), lists at most MAX_LISTED_PER_KIND
violations of a kind and never checks more configurations than its work bound."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_harness import gate_bounded
from hypothesis import event, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from payloads import ABSURD_FLOATS, HOME

from safety.gate import MAX_SAMPLES
from safety.violations import MAX_LISTED_PER_KIND

MARGIN = 0.05  # SafetyConfig's default joint margin


@st.composite
def trajectories(draw) -> np.ndarray:
    """Smooth moves, wild numbers anywhere in the float range, or smooth moves with absurd entries."""
    n = draw(st.integers(1, 40))
    kind = draw(st.sampled_from(["smooth", "wild", "spiked"]))
    if kind == "wild":
        return draw(arrays(np.float64, (n, 7), elements=st.floats(-1.7e308, 1.7e308)))
    steps = draw(arrays(np.float64, (n, 7), elements=st.floats(-0.08, 0.08)))
    q = np.asarray(HOME) + np.cumsum(steps, axis=0)
    if kind == "spiked":
        for _ in range(draw(st.integers(1, 3))):
            q[draw(st.integers(0, n - 1)), draw(st.integers(0, 6))] = draw(st.sampled_from([*ABSURD_FLOATS, 1e6, 50.0]))
    return q


safety_configs = st.fixed_dictionaries(
    {
        "collision_resolution_rad": st.floats(0.001, 0.05),
        "max_joint_step_rad": st.floats(0.001, 0.5),
        "padding_m": st.floats(0.0, 0.2),
    }
)


@settings(max_examples=40, deadline=None)
@given(
    q=trajectories(),
    dt=st.floats(1e-4, 10.0),
    safety=safety_configs,
    max_checks=st.sampled_from([1, 50, 5000, 1_000_000]),
)
def test_any_trajectory_gets_a_bounded_verdict(q, dt, safety, max_checks):
    s = gate_bounded(q, dt, safety, max_checks)
    event("ok" if s["ok"] else "refused")
    assert s["checked"] <= max_checks and s["json_ok"]
    assert all(n <= MAX_LISTED_PER_KIND for n in s["listed"].values())
    lower, upper = np.asarray(s["lower"]) + MARGIN, np.asarray(s["upper"]) - MARGIN
    outside = np.any((q < lower - 1e-9) | (q > upper + 1e-9))
    jumps = len(q) > 1 and np.any(np.abs(np.diff(q, axis=0)) > safety["max_joint_step_rad"] * (1 + 1e-6) + 1e-9)
    assert not outside or "joint_limit" in s["listed"]
    assert not jumps or "step" in s["listed"]
    assert (s["needed"] > max_checks) == ("unchecked" in s["listed"])
    if s["ok"]:
        assert not outside and not jumps and s["checked"] == s["needed"]


@pytest.mark.parametrize("jump", [1e300, -1e300, 1e6, 1.7e308])
def test_an_absurd_jump_is_refused_without_subsampling(jump):
    q = np.tile(HOME, (4, 1))
    q[2, 0] += jump
    s = gate_bounded(q, 0.004)
    assert not s["ok"] and {"joint_limit", "step", "velocity"} <= set(s["listed"])
    assert s["checked"] == 4 and s["rss_growth_mb"] < 100


def test_an_absurd_jump_between_absurd_positions():
    q = np.array([[-1.7e308, *HOME[1:]], [1.7e308, *HOME[1:]]])  # the difference overflows to inf
    s = gate_bounded(q, 0.004)
    assert not s["ok"] and s["checked"] == 2 and s["json_ok"]


def test_the_work_bound_is_an_unchecked_violation():
    q = np.tile(HOME, (3, 1))
    q[1, 0] += 2.0  # 200 sub-samples at 0.01 rad, then 200 back
    s = gate_bounded(q, 0.004, max_checks=150)
    assert not s["ok"] and s["checked"] == 150 and s["needed"] == 401
    assert s["listed"]["unchecked"] == 1


def test_too_many_samples_are_refused_unchecked():
    s = gate_bounded(np.tile(HOME, (MAX_SAMPLES + 1, 1)), 0.004)
    assert not s["ok"] and set(s["listed"]) == {"unchecked"} and s["checked"] == 0


def test_a_trajectory_wrong_everywhere_lists_a_bounded_number():
    """40,000 samples bouncing between far beyond both limits: some 1.5 million violations, a few thousand
    listed, memory and time bounded."""
    q = np.tile(HOME, (40_000, 1))
    q[::2] += 20.0
    q[1::2] -= 20.0
    s = gate_bounded(q, 0.004)
    assert not s["ok"] and s["omitted"] > 1_000_000
    assert all(n == MAX_LISTED_PER_KIND for k, n in s["listed"].items() if k not in ("workspace", "self_collision"))
    assert s["rss_growth_mb"] < 500
