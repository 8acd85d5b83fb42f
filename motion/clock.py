"""Clocks for the streaming executor: the wall clock on hardware (the stepped-simulation clock is
drivers.sim.SteppedClock)."""

from __future__ import annotations

import time
from typing import Protocol

# time.sleep overshoots by ~0.05-0.1 ms on Linux; the last stretch is spun so ticks start on time.
SPIN_S = 0.0003


class Clock(Protocol):
    def now(self) -> float:
        """Seconds on this clock's own monotonic time base."""

    def sleep_until(self, t: float) -> None:
        """Return at (or as soon as possible after) time t; at once if t has passed."""


class WallClock:
    """time.perf_counter with sleep-then-spin waiting (the spin is short, so other threads keep running)."""

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        remaining = t - time.perf_counter()
        if remaining > SPIN_S:
            time.sleep(remaining - SPIN_S)
        while time.perf_counter() < t:
            pass
