"""The controller's two TCP services on one loopback address: commands on 502, the 'real' report on 30003.

The SDK hard-codes both ports, so each emulator instance takes its own loopback address (all of 127.0.0.0/8 is
loopback on Linux): with no address given, the first of 127.0.0.2..127.0.0.254 where both ports can be bound,
starting at an offset from the process id, so parallel test processes rarely probe the same addresses. Binding
port 502 needs root or CAP_NET_BIND_SERVICE.

Each command connection has its own thread: requests are answered in order (the SDK waits for each reply). One
publisher thread runs the controller's cycle and sends the report to every report connection on an absolute
100 Hz schedule.
"""

from __future__ import annotations

import contextlib
import ipaddress
import logging
import os
import selectors
import socket
import threading
import time
from collections import deque

from drivers.xarm7.emulator.controller import ControllerModel
from drivers.xarm7.emulator.faults import TRUNCATED_BYTES, Faults
from drivers.xarm7.emulator.handlers import HANDLERS, Answer
from drivers.xarm7.emulator.wire import (
    COMMAND_PORT,
    PRIVATE_PROTOCOLS,
    REPORT_PORT,
    FrameReader,
    FramingError,
    Register,
    Request,
    Status,
    feedback,
    real_report,
    reply,
)

log = logging.getLogger(__name__)

REPORT_HZ = 100.0
REPORT_SEND_TIMEOUT_S = 1.0
REQUESTS_KEPT = 400_000  # the last half hour of requests served
REPORTS_KEPT = 12_000  # the last two minutes of reports sent, for latency measurements
CONTROLLER_PRIORITY = 20  # above the PC's streaming thread (10) and the SDK's (11): the controller is not the PC
LOOPBACK_HOSTS = range(2, 255)  # 127.0.0.N


def real_time(thread_id: int = 0) -> None:
    """The controller (and the robot behind it) is its own real-time system, whatever the PC's load: SCHED_FIFO
    for a thread (0: the calling one) where permitted (root or CAP_SYS_NICE), a normal thread otherwise."""
    with contextlib.suppress(OSError, AttributeError):
        os.sched_setscheduler(thread_id, os.SCHED_FIFO, os.sched_param(CONTROLLER_PRIORITY))


class EmulatorBindError(OSError):
    """No loopback address had both controller ports free (or binding port 502 is not permitted)."""


def _listen(address: str, port: int) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        s.bind((address, port))
        s.listen(4)
    except OSError:
        s.close()
        raise
    return s


def _bind_pair(address: str) -> tuple[socket.socket, socket.socket]:
    command = _listen(address, COMMAND_PORT)
    try:
        return command, _listen(address, REPORT_PORT)
    except OSError:
        command.close()
        raise


def bind_controller_ports(address: str | None) -> tuple[str, socket.socket, socket.socket]:
    """Listening sockets on (address, 502) and (address, 30003); address None: a free 127.0.0.N."""
    if address is not None:
        if not ipaddress.ip_address(address).is_loopback:
            raise ValueError(f"the emulator listens on loopback only, not {address}")
        try:
            return address, *_bind_pair(address)
        except OSError as e:
            raise EmulatorBindError(
                f"cannot listen on {address}:{COMMAND_PORT} and :{REPORT_PORT}: {e} (another emulator there? "
                "port 502 needs root or CAP_NET_BIND_SERVICE)"
            ) from e
    start = os.getpid() % len(LOOPBACK_HOSTS)
    last: OSError | None = None
    for i in range(len(LOOPBACK_HOSTS)):
        candidate = f"127.0.0.{LOOPBACK_HOSTS[(start + i) % len(LOOPBACK_HOSTS)]}"
        try:
            return candidate, *_bind_pair(candidate)
        except OSError as e:
            last = e
    raise EmulatorBindError(
        f"no loopback address 127.0.0.2-254 has ports {COMMAND_PORT} and {REPORT_PORT} free: {last} "
        "(port 502 needs root or CAP_NET_BIND_SERVICE)"
    )


class ControllerServer:
    def __init__(self, model: ControllerModel, faults: Faults, address: str | None, report_hz: float) -> None:
        self.model, self.faults = model, faults
        self.address, self._command_listener, self._report_listener = bind_controller_ports(address)
        self.period = 1.0 / report_hz
        self._running = threading.Event()
        self._lock = threading.Lock()
        self._command_links: list[socket.socket] = []
        self._report_links: list[socket.socket] = []
        self._threads: list[threading.Thread] = []
        self.requests: deque[tuple[float, int]] = deque(maxlen=REQUESTS_KEPT)  # (time.monotonic(), register)
        self.unknown: list[int] = []  # registers the emulator does not implement (answered invalid)
        self.sent_reports: deque[tuple[float, bytes]] = deque(maxlen=REPORTS_KEPT)  # (time.monotonic(), frame)
        self.connections = {"command": 0, "report": 0}

    # -- lifecycle ----------------------------------------------------------------------------------------
    def start(self) -> None:
        self._running.set()
        for target, name in ((self._accept, "accept"), (self._publish, "report")):
            self._spawn(target, f"xarm-emulator-{name}")

    def _spawn(self, target, name: str, *args) -> None:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        t.start()
        with self._lock:
            self._threads = [x for x in self._threads if x.is_alive()] + [t]

    def stop(self) -> None:
        self._running.clear()
        self._close_listeners()
        self.drop_command_link()
        self.drop_report_link()
        with self._lock:
            threads = list(self._threads)
        for t in threads:
            if t is not threading.current_thread():
                t.join(timeout=2.0)

    # -- link faults --------------------------------------------------------------------------------------
    def _close_listeners(self) -> None:
        with self._lock:
            listeners, self._command_listener, self._report_listener = (
                (self._command_listener, self._report_listener),
                None,
                None,
            )
        for s in listeners:
            if s is not None:
                s.close()

    def refuse_connections(self) -> None:
        """Stop listening: a new connection is refused (established ones stay)."""
        self.faults.refusing = True
        self._close_listeners()
        self.faults.fire("refused connection")

    def accept_connections(self) -> None:
        with self._lock:
            if self._command_listener is None:
                self._command_listener, self._report_listener = _bind_pair(self.address)
        self.faults.refusing = False

    def _drop(self, links: list[socket.socket]) -> int:
        with self._lock:
            dropped, links[:] = list(links), []
        for s in dropped:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()
        return len(dropped)

    def drop_command_link(self) -> None:
        if self._drop(self._command_links) and self._running.is_set():
            self.faults.fire("command link dropped")

    def drop_report_link(self) -> None:
        if self._drop(self._report_links) and self._running.is_set():
            self.faults.fire("report link dropped")

    # -- accepting ----------------------------------------------------------------------------------------
    def _accept(self) -> None:
        while self._running.is_set():
            with self._lock:
                listeners = [s for s in (self._command_listener, self._report_listener) if s is not None]
            if not listeners:
                time.sleep(0.01)
                continue
            with selectors.DefaultSelector() as sel:
                try:
                    for s in listeners:
                        sel.register(s, selectors.EVENT_READ)
                    ready = sel.select(timeout=0.05)
                except (OSError, ValueError):  # a listener was closed under us (refuse_connections, stop)
                    continue
                for key, _ in ready:
                    try:
                        link, _peer = key.fileobj.accept()
                    except OSError:
                        continue
                    link.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    if key.fileobj.getsockname()[1] == COMMAND_PORT:
                        # blocking: the SDK sets a process-wide default socket timeout of 1 s, which an accepted
                        # socket would inherit, closing an idle command link (in-process clients only)
                        link.settimeout(None)
                        with self._lock:
                            self._command_links.append(link)
                        self.connections["command"] += 1
                        self._spawn(self._serve, "xarm-emulator-command", link)
                    else:
                        link.settimeout(REPORT_SEND_TIMEOUT_S)  # a client that stops reading is dropped
                        with self._lock:
                            self._report_links.append(link)
                        self.connections["report"] += 1

    # -- commands -----------------------------------------------------------------------------------------
    def _serve(self, link: socket.socket) -> None:
        real_time()
        reader = FrameReader()
        try:
            while self._running.is_set():
                data = link.recv(4096)
                if not data:
                    break
                for request in reader.feed(data):
                    self._answer(link, request)
        except FramingError as e:
            log.warning("xArm emulator: closing a command connection: %s", e)
        except OSError:
            pass  # dropped (a fault, stop(), or the client went away)
        finally:
            with self._lock:
                if link in self._command_links:
                    self._command_links.remove(link)
            link.close()

    def _answer(self, link: socket.socket, request: Request) -> None:
        if request.protocol not in PRIVATE_PROTOCOLS:
            return  # heartbeats and standard Modbus-TCP frames: the driver sends none
        self.requests.append((time.monotonic(), request.register))
        handler = HANDLERS.get(request.register)
        if handler is None:
            self.unknown.append(request.register)
            answer = Answer(valid=False)
        else:
            try:
                answer = handler(self.model, request)
            except ValueError as e:
                log.warning("xArm emulator: register %d: %s", request.register, e)
                answer = Answer(valid=False)
        if request.register == Register.SERVO_J and answer.valid:
            self.faults.count_setpoint()
        status = self.model.status() | (Status.OK if answer.valid else Status.INVALID)
        frame = reply(request, status, answer.payload)
        stall = self.faults.take_stall(request.register)
        if stall:
            time.sleep(stall)  # the controller's known stall: the command was executed, the reply comes late
        how = self.faults.take_corruption(request.register)
        if how == "protocol":
            frame = frame[:2] + bytes([0x7F, 0x7F]) + frame[4:]
        elif how == "truncate":
            frame = frame[:TRUNCATED_BYTES]
        link.sendall(frame)
        if answer.feedback_kind is not None and how is None:
            link.sendall(feedback(request, answer.feedback_kind))

    # -- report -------------------------------------------------------------------------------------------
    def _publish(self) -> None:
        real_time()
        t_next = time.monotonic()
        while self._running.is_set():
            t_next += self.period
            delay = t_next - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                t_next = time.monotonic()  # behind (machine stalled): restart the schedule, never burst
            self.model.tick()
            if self.faults.report_silent:
                continue
            frame = real_report(*self.model.report())
            with self._lock:
                links = list(self._report_links)
            for s in links:
                try:
                    s.sendall(frame)
                except OSError:
                    with self._lock:
                        if s in self._report_links:
                            self._report_links.remove(s)
                    s.close()
            self.sent_reports.append((time.monotonic(), frame))
