"""Publishes the run's state: on every transition, and again twice a second so a console that joins late (or
missed a sample) always shows the current state within 0.5 s."""

from __future__ import annotations

import threading
import time

from runtime.messaging.bus import Bus
from runtime.messaging.messages import Event, Status
from runtime.supervision.states import StateMachine, Transition

REPUBLISH_PERIOD_S = 0.5


class StatusPublisher:
    def __init__(self, bus: Bus, machine: StateMachine) -> None:
        self.bus, self.machine = bus, machine
        self.run_id = self.plan_id = self.instruction = ""
        self._last: Transition | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._repeat, name="status", daemon=True)
        machine.add_listener(self._on_transition)

    def start(self) -> StatusPublisher:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)

    def _on_transition(self, t: Transition) -> None:
        self._last = t
        self.publish()

    def publish(self) -> None:
        t = self._last
        self.bus.publish(
            self.bus.keys.status,
            Status(
                stamp_s=time.time(),
                state=self.machine.state.value,
                previous=t.previous.value if t else "",
                reason=self.machine.reason,
                run_id=self.run_id,
                plan_id=self.plan_id,
                instruction=self.instruction,
                seconds_in_previous=t.seconds_in_previous if t else 0.0,
            ),
        )

    def event(self, text: str, level: str = "info") -> None:
        self.bus.publish(self.bus.keys.events, Event(stamp_s=time.time(), level=level, text=text, run_id=self.run_id))

    def _repeat(self) -> None:
        while not self._stop.wait(REPUBLISH_PERIOD_S):
            self.publish()
