"""At most a few notices per period, the rest counted: a flood of bad input must not become a flood of logs or
events (or the memory and time they cost), while the first of each kind is always told."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable


class Throttle:
    def __init__(self, per_period: int = 5, period_s: float = 1.0, clock: Callable[[], float] = time.monotonic):
        self.per_period, self.period_s, self._clock = per_period, period_s, clock
        self._lock = threading.Lock()
        self._window_start = -float("inf")
        self._told = 0
        self._held = 0  # notices held back since the last one told

    def admit(self) -> int | None:
        """None: hold this notice back (counted). Otherwise tell it, with how many were held back before it."""
        with self._lock:
            now = self._clock()
            if now - self._window_start >= self.period_s:
                self._window_start, self._told = now, 0
            if self._told >= self.per_period:
                self._held += 1
                return None
            self._told += 1
            held, self._held = self._held, 0
            return held

    def tell(self, text: str, say: Callable[[str], None]) -> bool:
        """say(text) unless held back; a told notice names how many were held back before it."""
        held = self.admit()
        if held is None:
            return False
        say(text if not held else f"{text} ({held} earlier notices held back)")
        return True
