"""Raw HTTP on the loopback for the console tests: requests exactly as written (bad ones included), answers
parsed by hand, and a hub that records what the console publishes."""

from __future__ import annotations

import json
import socket
import threading
import time
from dataclasses import dataclass

from runtime.messaging.bus import Bus


@dataclass
class Answer:
    status: int
    headers: dict[str, str]
    body: bytes
    seconds: float

    def json(self) -> dict:
        return json.loads(self.body)


def read_answer(sock: socket.socket, t0: float) -> Answer:
    data = b""
    while b"\r\n\r\n" not in data:
        chunk = sock.recv(65536)
        if not chunk:
            raise ConnectionError(f"closed before an answer: {data!r}")
        data += chunk
    head, _, rest = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    status = int(lines[0].split()[1])
    headers = {k.strip().lower(): v.strip() for k, _, v in (line.partition(":") for line in lines[1:])}
    length = int(headers.get("content-length", "0"))
    while len(rest) < length:
        chunk = sock.recv(65536)
        if not chunk:
            break
        rest += chunk
    return Answer(status, headers, rest[:length], time.monotonic() - t0)


def send(port: int, raw: bytes, timeout_s: float = 10.0, shut_write: bool = False) -> Answer:
    """One request as given; the answer (or an exception when none came within timeout_s)."""
    with socket.create_connection(("127.0.0.1", port), timeout=timeout_s) as sock:
        t0 = time.monotonic()
        sock.sendall(raw)
        if shut_write:
            sock.shutdown(socket.SHUT_WR)
        return read_answer(sock, t0)


def post(port: int, action: str, body: bytes, *, host: str | None = None, headers: dict | None = None) -> Answer:
    hdrs = {"Host": host or f"127.0.0.1:{port}", "X-Goalvla": "1", "Content-Type": "application/json"}
    hdrs |= {"Content-Length": str(len(body))} | (headers or {})
    head = "".join(f"{k}: {v}\r\n" for k, v in hdrs.items() if v is not None)
    return send(port, f"POST /api/{action} HTTP/1.1\r\n{head}\r\n".encode() + body)


def get(port: int, path: str, *, host: str | None = None, headers: dict | None = None) -> Answer:
    hdrs = {"Host": host or f"127.0.0.1:{port}", "Connection": "close"} | (headers or {})
    head = "".join(f"{k}: {v}\r\n" for k, v in hdrs.items() if v is not None)
    return send(port, f"GET {path} HTTP/1.1\r\n{head}\r\n".encode())


class Hub:
    """The runtime's side of the bus, recording every sample the console publishes on the action keys."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.samples: dict[str, list[bytes]] = {"confirm": [], "command": [], "estop": []}
        self._lock = threading.Lock()
        for name in self.samples:
            bus.subscribe_bytes(getattr(bus.keys, name), lambda k, p, n=name: self._got(n, p))

    def _got(self, name: str, payload: bytes) -> None:
        with self._lock:
            self.samples[name].append(payload)

    def messages(self, name: str) -> list[dict]:
        with self._lock:
            return [json.loads(p) for p in self.samples[name]]
