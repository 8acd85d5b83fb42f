"""The confirm gate: execution needs an operator's approval of this exact plan id.

Every approval arrives as a `confirm` message, whoever sends it (console button, terminal prompt, or `--yes`,
which the run publishes itself so it takes the same path). A confirm for any other plan id is rejected and
reported: it was meant for a plan the operator saw earlier, not the one about to run.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from runtime.messaging.bus import Bus
from runtime.messaging.messages import Confirm, printable


class ConfirmGate:
    def __init__(self, bus: Bus, on_reject: Callable[[str], None]) -> None:
        """on_reject(text) tells the operator about a rejected confirm (it should throttle a flood)."""
        self.bus = bus
        self._on_reject = on_reject
        self._lock = threading.Lock()
        self._expected: str | None = None
        self._decision: Confirm | None = None
        self._decided = threading.Event()
        self.rejected: deque[Confirm] = deque(maxlen=100)  # the latest, for the record; a flood costs nothing
        bus.subscribe(bus.keys.confirm, Confirm, self._on_confirm)

    def expect(self, plan_id: str) -> None:
        """Arm the gate for one plan; earlier decisions are forgotten."""
        with self._lock:
            self._expected, self._decision = plan_id, None
            self._decided.clear()

    def _on_confirm(self, _key: str, msg: Confirm) -> None:
        with self._lock:
            expected = self._expected
            if expected is not None and msg.plan_id == expected and self._decision is None:
                self._decision = msg
                self._decided.set()
                return
            self.rejected.append(msg)
        waiting = f"awaiting plan {expected}" if expected else "no plan is awaiting confirmation"
        self._on_reject(f"confirm from {printable(msg.source)} for plan {printable(msg.plan_id)} rejected: {waiting}")

    def wait(self, cancel: threading.Event, poll_s: float = 0.02) -> Confirm | None:
        """Block until a decision for the expected plan arrives (returned) or `cancel` is set (None).
        The timeout is the AWAITING_CONFIRM budget, which the supervisor enforces by cancelling."""
        while not cancel.is_set():
            if self._decided.wait(poll_s):
                with self._lock:
                    self._expected = None
                    return self._decision
        with self._lock:
            self._expected = None
        return None

    def send(self, plan_id: str, source: str, approve: bool = True) -> None:
        self.bus.publish(
            self.bus.keys.confirm, Confirm(stamp_s=time.time(), plan_id=plan_id, source=source, approve=approve)
        )
