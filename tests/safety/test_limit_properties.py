"""Property tests (hypothesis) of the limit checks against brute-force definitions."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from safety.config import SafetyConfig
from safety.gate import subsample
from safety.limits import derivative_violations, joint_limit_violations, rest_padded_derivative, step_violations

NAMES = tuple(f"joint{i}" for i in range(1, 4))
LOWER, UPPER = np.array([-1.0, -2.0, -0.5]), np.array([1.0, 2.0, 3.0])
finite = st.floats(-4.0, 4.0, allow_nan=False, allow_infinity=False)
positions = st.integers(1, 30).flatmap(lambda n: arrays(np.float64, (n, 3), elements=finite))
small_steps = (
    st.integers(2, 30)
    .flatmap(lambda n: arrays(np.float64, (n, 3), elements=st.floats(-0.05, 0.05, allow_nan=False)))
    .map(lambda d: np.cumsum(d, axis=0))
)
common = settings(max_examples=60, deadline=None)


@common
@given(q=positions, margin=st.floats(0.0, 0.4))
def test_joint_limit_flags_exactly_the_samples_outside(q, margin):
    times = np.arange(len(q)) * 0.01
    found = {
        (round(v.time_s / 0.01), NAMES.index(v.names[0]))
        for v in joint_limit_violations(q, times, NAMES, LOWER, UPPER, margin)
    }
    expected = {
        (k, j) for k in range(len(q)) for j in range(3) if not LOWER[j] + margin <= q[k, j] <= UPPER[j] - margin
    }
    assert found == expected


@common
@given(q=positions, margin=st.floats(0.0, 0.2), extra=st.floats(0.0, 0.2))
def test_larger_margin_never_removes_a_joint_limit_violation(q, margin, extra):
    times = np.arange(len(q)) * 0.01
    loose = joint_limit_violations(q, times, NAMES, LOWER, UPPER, margin)
    tight = joint_limit_violations(q, times, NAMES, LOWER, UPPER, margin + extra)
    assert {(v.time_s, v.names) for v in loose} <= {(v.time_s, v.names) for v in tight}


@common
@given(q=small_steps, dt=st.floats(0.002, 0.05), vmax=st.floats(0.1, 3.0))
def test_velocity_violation_iff_some_step_is_faster_than_the_limit(q, dt, vmax):
    cfg = SafetyConfig(max_joint_velocity_rad_s=vmax)
    found = [v for v in derivative_violations(q, dt, NAMES, cfg, np.full(3, 10.0)) if v.kind == "velocity"]
    fastest = np.max(np.abs(np.diff(q, axis=0)), initial=0.0) / dt
    assert bool(found) == (fastest > vmax * (1 + 1e-9) + 1e-12)
    assert all(abs(v.value) > vmax for v in found)


@common
@given(q=small_steps, dt=st.floats(0.002, 0.05))
def test_stationary_or_scaled_down_motion_is_never_worse(q, dt):
    cfg = SafetyConfig()
    n_full = len(derivative_violations(q, dt, NAMES, cfg, np.full(3, 10.0)))
    slower = derivative_violations(q, dt * 2, NAMES, cfg, np.full(3, 10.0))  # same path, half the speed
    assert len(slower) <= n_full
    assert derivative_violations(np.repeat(q[:1], len(q), axis=0), dt, NAMES, cfg, np.full(3, 10.0)) == []


@common
@given(q=small_steps, dt=st.floats(0.002, 0.05), order=st.integers(1, 3))
def test_rest_padded_derivatives_vanish_outside_the_motion(q, dt, order):
    d, ends = rest_padded_derivative(q, dt, order)
    assert np.all(d[ends <= 0] == 0)  # at rest before the first sample
    assert np.all(d[ends >= len(q) + order] == 0)  # and holding the last one long enough afterwards


@common
@given(q=small_steps, max_step=st.floats(0.005, 0.2))
def test_step_flags_exactly_the_large_jumps(q, max_step):
    times = np.arange(len(q)) * 0.004
    found = {(round(v.time_s / 0.004), v.names[0]) for v in step_violations(q, times, NAMES, max_step)}
    steps = np.abs(np.diff(q, axis=0))
    expected = {(k + 1, NAMES[j]) for k, j in zip(*np.nonzero(steps > max_step * (1 + 1e-9) + 1e-12), strict=True)}
    assert found == expected


@common
@given(q=small_steps, resolution=st.floats(0.001, 0.05))
def test_subsample_never_moves_a_joint_more_than_the_resolution(q, resolution):
    configs, times = subsample(q, 0.004, resolution)
    assert np.all(np.abs(np.diff(configs, axis=0)) <= resolution + 1e-12)
    np.testing.assert_allclose(configs[0], q[0])
    np.testing.assert_allclose(configs[-1], q[-1])
    assert np.all(np.diff(times) > 0)
