"""E-stop nodes: a liveliness token, heartbeats at `heartbeat_rate_hz`, and a stop message on demand.

`goalvla estop` runs one in a terminal: any key sends an e-stop (the node keeps running so the operator can
reset and carry on), Ctrl-C or closing the terminal sends one and exits. Execution requires a heartbeat from
some e-stop node younger than the deadman timeout, so a dead or frozen node stops the robot too.

The sim profile may run the node inside `goalvla run` (runtime.estop_node: in_process) so CI can run unattended;
the runner refuses that on any hardware profile.

On the receiving side every sample on the estop key stops the robot; `estop_reason` is what the run records.
"""

from __future__ import annotations

import os
import sys
import termios
import threading
import time
import tty

from runtime.messaging.bus import Bus
from runtime.messaging.messages import EStop, Heartbeat, MessageRefused, decode, printable


def estop_reason(payload: bytes) -> str:
    """The reason an e-stop sample gives, or what was wrong with its payload (it stops the robot either way)."""
    try:
        msg = decode(EStop, payload, time.time())
    except MessageRefused as e:
        return f"e-stop sample with a bad payload ({e}): stopped all the same"
    return f"{printable(msg.reason, 300)} (from {printable(msg.source, 64)})"


class EStopNode:
    def __init__(self, bus: Bus, node: str, rate_hz: float) -> None:
        self.bus, self.node, self.period = bus, node, 1.0 / rate_hz
        self._seq = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._beat, name=f"estop-{node}", daemon=True)
        self.paused = threading.Event()  # tests: stop beating without disappearing (a frozen node)

    def start(self) -> EStopNode:
        self.bus.declare_token(self.bus.keys.alive_of("estop", self.node))
        self._thread.start()
        return self

    def press(self, reason: str = "e-stop pressed") -> None:
        self.bus.publish(self.bus.keys.estop, EStop(stamp_s=time.time(), source=self.node, reason=reason))

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)

    def _beat(self) -> None:
        key = self.bus.keys.heartbeat_of(self.node)
        next_t = time.monotonic()
        while not self._stop.is_set():
            if not self.paused.is_set():
                self._seq += 1
                self.bus.publish(key, Heartbeat(stamp_s=time.time(), node=self.node, kind="estop", seq=self._seq))
            next_t = max(next_t + self.period, time.monotonic())
            self._stop.wait(max(0.0, next_t - time.monotonic()))


def run_terminal_node(bus: Bus, node: str, rate_hz: float, echo=print) -> None:
    """The interactive node behind `goalvla estop`: runs until Ctrl-C or end of input (both send an e-stop)."""
    estop = EStopNode(bus, node, rate_hz).start()
    is_tty = sys.stdin.isatty()
    saved = termios.tcgetattr(sys.stdin) if is_tty else None
    echo(f"e-stop node '{node}' armed on {bus.keys.root}: ANY KEY = E-STOP, Ctrl-C = E-STOP and quit")
    try:
        if is_tty:
            tty.setcbreak(sys.stdin.fileno())
        while True:
            key = os.read(sys.stdin.fileno(), 1).decode(errors="replace")  # Ctrl-C interrupts the read
            if key == "":
                estop.press("e-stop node input closed")
                echo("input closed: E-STOP sent, quitting")
                return
            estop.press("e-stop key pressed")
            echo("E-STOP sent. Check the cell, then press Reset on the console.")
    except KeyboardInterrupt:
        estop.press("e-stop node interrupted (Ctrl-C)")
        echo("Ctrl-C: E-STOP sent, quitting")
    finally:
        if saved is not None:
            termios.tcsetattr(sys.stdin, termios.TCSADRAIN, saved)
        estop.close()
