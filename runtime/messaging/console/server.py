"""`goalvla console`: serves the operator page and bridges it to Zenoh (runtime.messaging.console.bridge).

Downstream, one server-sent-events stream per page carries status, events, plan summaries, throttled joint
states and "image updated" notices (the page then fetches /image/<name>). Upstream, small JSON POSTs become
Zenoh messages: command (run, abort, reset), confirm (with the plan id the page shows) and estop.

The server is the standard library's threaded HTTP/1.1 server, held to what an operator page needs: every
request's Host and Origin are this console's (runtime.messaging.console.guard); POSTs carry the X-Goalvla
header, a Content-Length of at most MAX_BODY_BYTES (read within BODY_TIMEOUT_S) and a strict JSON object; the
E-STOP is published before its body is even looked at. Connections are capped, idle ones time out, a stalled
event stream is dropped after STREAM_WRITE_TIMEOUT_S, client disconnects are not errors, and Ctrl-C ends it at
once. Every refusal is a 4xx with a JSON `error` naming the problem.
"""

from __future__ import annotations

import contextlib
import json
import logging
import queue
import signal
import socket
import sys
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources

from runtime.config import RuntimeConfig
from runtime.messaging.bus import Bus
from runtime.messaging.console.bridge import ACTIONS, ActionRefused, Bridge, PageStream
from runtime.messaging.console.guard import Guard, Refusal
from runtime.messaging.messages import MessageRefused, read_json

log = logging.getLogger(__name__)

KEEPALIVE_S = 1.0
MAX_BODY_BYTES = 16 * 1024  # the page posts a few hundred bytes at most
MAX_REQUEST_LINE_BYTES = 65536  # as http.server reads the first request line
BODY_TIMEOUT_S = 2.0  # a body shorter than its Content-Length is refused after this, not waited for
IDLE_TIMEOUT_S = 10.0  # a connection that sends nothing for this long is closed
STREAM_WRITE_TIMEOUT_S = 5.0  # a page that takes no events for this long is dropped
MAX_CONNECTIONS = 64
POLL_S = 0.1  # how often the server looks for a shutdown request
STATIC = {
    "/": ("index.html", "text/html"),
    "/app.js": ("app.js", "text/javascript"),
    "/style.css": ("style.css", "text/css"),
}
SECURITY_HEADERS = {
    "Cache-Control": "no-store",
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Content-Security-Policy": "default-src 'self'; frame-ancestors 'none'",
    "Referrer-Policy": "no-referrer",
}
GONE = (ConnectionError, TimeoutError)  # the client left, reset, or stopped reading: not the console's error


class Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    timeout = IDLE_TIMEOUT_S
    server: ConsoleHTTPServer

    def log_message(self, fmt: str, *args) -> None:
        log.debug("console http %s: " + fmt, self.client_address[0], *args)

    # -- answers ----------------------------------------------------------------------------------------------
    def _send(self, status: int, body: bytes, content_type: str, extra: dict | None = None) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        for k, v in {**SECURITY_HEADERS, **(extra or {})}.items():
            self.send_header(k, v)
        if self.close_connection:
            self.send_header("Connection", "close")
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(body)

    def _json(self, status: int, doc: dict) -> None:
        self._send(status, json.dumps(doc).encode(), "application/json")

    def _refuse(self, refusal: Refusal, close: bool = False, **extra) -> None:
        self.close_connection = self.close_connection or close
        self._json(refusal.status, {"error": refusal.reason, **extra})

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (bad request lines, headers, methods), as 4xx JSON like every other."""
        code = int(code)
        if code == HTTPStatus.NOT_IMPLEMENTED:  # a method this console does not have
            code, message = HTTPStatus.METHOD_NOT_ALLOWED, f"method {self.command!r} not allowed (GET, POST)"
        elif code >= 500:  # 505: an HTTP version it does not speak is the request's problem
            code = HTTPStatus.BAD_REQUEST
        self.close_connection = True
        self.request_version = "HTTP/1.1"  # (http.server answers a request it could not parse without a status line)
        reason = message or HTTPStatus(code).phrase
        try:
            extra = {"Allow": "GET, POST"} if code == HTTPStatus.METHOD_NOT_ALLOWED else None
            self._send(code, json.dumps({"error": reason}).encode(), "application/json", extra)
        except GONE:
            pass

    def parse_request(self) -> bool:
        # blank lines before the request line are skipped (RFC 9112 2.2): http.server would close without a word
        skipped = 0
        while self.raw_requestline and not self.raw_requestline.strip():
            skipped += len(self.raw_requestline)
            if skipped > MAX_REQUEST_LINE_BYTES:
                return self._refuse_line(HTTPStatus.BAD_REQUEST, "only blank lines where the request line should be")
            self.raw_requestline = self.rfile.readline(MAX_REQUEST_LINE_BYTES + 1)
        if len(self.raw_requestline) > MAX_REQUEST_LINE_BYTES:
            return self._refuse_line(HTTPStatus.REQUEST_URI_TOO_LONG)
        if not super().parse_request():
            return False
        if self.request_version not in ("HTTP/1.0", "HTTP/1.1"):  # HTTP/0.9 answers carry no status: refuse it
            self.send_error(HTTPStatus.BAD_REQUEST, f"{self.request_version} is not spoken here (HTTP/1.1)")
            return False
        return True

    def _refuse_line(self, code: HTTPStatus, message: str | None = None) -> bool:
        """A refusal before any request line was parsed (as http.server's own for a line too long); False."""
        self.requestline, self.command = "", ""
        self.send_error(code, message)
        return False

    def _admit(self) -> bool:
        refusal = self.server.guard.check(self.headers, self.connection.getsockname()[0])
        if refusal is not None:
            self._refuse(refusal, close=True)
            return False
        return True

    # -- GET ----------------------------------------------------------------------------------------------------
    def do_GET(self) -> None:
        if not self._admit():
            return
        if self.headers.get("Transfer-Encoding") or self.headers.get("Content-Length", "0").strip() != "0":
            self.close_connection = True  # a GET body is never read: nothing after it can be trusted as a request
        path = self.path.split("?", 1)[0]
        bridge = self.server.bridge
        if path in STATIC:
            name, ctype = STATIC[path]
            body = resources.files("runtime.messaging.console").joinpath("static", name).read_bytes()
            self._send(HTTPStatus.OK, body, f"{ctype}; charset=utf-8")
        elif path.startswith("/image/"):
            _version, data = bridge.images.get(path.removeprefix("/image/"), (0, b""))
            if not data:
                self._refuse(Refusal(HTTPStatus.NOT_FOUND, "no such image yet"))
            else:
                self._send(HTTPStatus.OK, data, "image/jpeg")
        elif path == "/events":
            self._stream()
        else:
            self._refuse(Refusal(HTTPStatus.NOT_FOUND, "not found"))

    def _stream(self) -> None:
        bridge = self.server.bridge
        self.close_connection = True
        self.connection.settimeout(STREAM_WRITE_TIMEOUT_S)
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "text/event-stream")
        for k, v in SECURITY_HEADERS.items():
            self.send_header(k, v)
        self.send_header("Connection", "close")
        self.end_headers()
        page = bridge.attach()
        try:
            self.wfile.write(b"retry: 1000\n\n")  # a dropped page reconnects within a second
            self._pump(page)
        except GONE:
            pass  # the page left, or stopped taking events for STREAM_WRITE_TIMEOUT_S
        finally:
            bridge.detach(page)

    def _pump(self, page: PageStream) -> None:
        bridge = self.server.bridge
        while not page.dropped.is_set() and not bridge.closed.is_set():
            try:
                frame = page.events.get(timeout=KEEPALIVE_S)
            except queue.Empty:
                frame = b": keep-alive\n\n"
            self.wfile.write(frame)

    # -- POST ---------------------------------------------------------------------------------------------------
    def do_POST(self) -> None:
        if not self._admit():
            return
        action = self.path.split("?", 1)[0].removeprefix("/api/")
        if not self.path.startswith("/api/") or action not in ACTIONS:
            self._refuse(Refusal(HTTPStatus.NOT_FOUND, "unknown action"), close=True)
            return
        if self.headers.get("X-Goalvla") != "1":
            self._refuse(Refusal(HTTPStatus.FORBIDDEN, "missing X-Goalvla header"), close=True)
            return
        bridge = self.server.bridge
        if action == "estop":
            bridge.estop()  # before the body: a malformed e-stop request still stops
        try:
            body = self._body()
            if action != "estop":
                bridge.act(action, body)
        except (BodyRefused, MessageRefused, ActionRefused) as e:
            status = getattr(e, "status", HTTPStatus.BAD_REQUEST)
            extra = {"estop_sent": True} if action == "estop" else {}
            self._refuse(Refusal(status, str(e)), close=getattr(e, "close", False), **extra)
            return
        self._json(HTTPStatus.OK, {"ok": True, "action": action})

    def _body(self) -> dict:
        """The request's JSON object ({} when it has none), read within BODY_TIMEOUT_S."""
        if self.headers.get_all("Transfer-Encoding"):
            raise BodyRefused(HTTPStatus.LENGTH_REQUIRED, "send a Content-Length; chunked bodies are not accepted")
        lengths = self.headers.get_all("Content-Length") or []
        if len(lengths) > 1:
            raise BodyRefused(HTTPStatus.BAD_REQUEST, "more than one Content-Length")
        text = lengths[0].strip() if lengths else "0"
        if not (text.isascii() and text.isdigit() and len(text) <= 12):
            raise BodyRefused(HTTPStatus.BAD_REQUEST, "Content-Length must be a number of bytes")
        length = int(text)
        if length > MAX_BODY_BYTES:
            raise BodyRefused(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"body of {length} bytes (limit {MAX_BODY_BYTES})")
        raw = self._read(length)
        return read_json(raw) if raw else {}

    def _read(self, length: int) -> bytes:
        deadline = time.monotonic() + BODY_TIMEOUT_S
        chunks, got = [], 0
        try:
            while got < length:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError
                self.connection.settimeout(left)
                chunk = self.rfile.read1(length - got)
                if not chunk:
                    break
                chunks.append(chunk)
                got += len(chunk)
        except TimeoutError:
            pass
        finally:
            self.connection.settimeout(IDLE_TIMEOUT_S)
        if got < length:
            raise BodyRefused(HTTPStatus.BAD_REQUEST, f"body of {got} bytes, shorter than its Content-Length {length}")
        return b"".join(chunks)


class BodyRefused(ValueError):
    """A request body that is not read (or not in full); the connection is closed after the answer."""

    close = True

    def __init__(self, status: HTTPStatus, reason: str) -> None:
        super().__init__(reason)
        self.status = status


class ConsoleHTTPServer(ThreadingHTTPServer):
    """ThreadingHTTPServer with a cap on connections and quiet client disconnects."""

    daemon_threads = True
    block_on_close = False
    request_queue_size = 2 * MAX_CONNECTIONS  # a burst waits to be answered (or refused), never a lost connect

    def __init__(self, address: tuple[str, int], bridge: Bridge, extra_hosts: frozenset[str] = frozenset()):
        self.address_family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
        super().__init__(address, Handler)
        self.bridge = bridge
        self.guard = Guard(self.server_address[1], frozenset(h.lower() for h in extra_hosts))
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)
        self.closing = False

    def process_request(self, request: socket.socket, client_address) -> None:
        if not self._slots.acquire(blocking=False):
            body = b'{"error": "too many connections"}'
            head = f"HTTP/1.1 429 Too Many Requests\r\nContent-Type: application/json\r\nContent-Length: {len(body)}"
            with contextlib.suppress(OSError):  # (on the accepting thread: a short answer, never a long wait)
                request.settimeout(0.2)
                request.sendall(f"{head}\r\nRetry-After: 1\r\nConnection: close\r\n\r\n".encode() + body)
            self.shutdown_request(request)
            return
        super().process_request(request, client_address)

    def process_request_thread(self, request: socket.socket, client_address) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()

    def handle_error(self, request: socket.socket, client_address) -> None:
        error = sys.exc_info()[1]
        if isinstance(error, GONE) or (self.closing and isinstance(error, OSError)):
            log.debug("console: client %s left (%s)", client_address, type(error).__name__)
        else:
            log.error("console: request from %s failed", client_address, exc_info=error)


class ConsoleServer:
    """The bridge plus its HTTP server; `start()` serves on a background thread (tests), `serve_forever` blocks."""

    def __init__(
        self,
        cfg: RuntimeConfig,
        host: str = "127.0.0.1",
        port: int = 8080,
        extra_hosts: frozenset[str] = frozenset(),
    ) -> None:
        self.bus = Bus(cfg.zenoh, cfg.robot_id, "connect")
        self.bridge = Bridge(self.bus)
        try:
            self.http = ConsoleHTTPServer((host, port), self.bridge, extra_hosts)
        except OSError:
            self.bridge.close()
            self.bus.close()
            raise
        shown = f"[{host}]" if ":" in host else host
        self.url = f"http://{shown}:{self.http.server_address[1]}/"
        self._thread: threading.Thread | None = None

    def start(self) -> ConsoleServer:
        self._thread = threading.Thread(target=self.serve_forever, name="console-http", daemon=True)
        self._thread.start()
        return self

    def serve_forever(self) -> None:
        self.http.serve_forever(poll_interval=POLL_S)

    def close(self) -> None:
        """Ends the event streams and the server; quick, whatever the pages do."""
        self.http.closing = True
        self.bridge.close()
        if self._thread is not None:
            self.http.shutdown()
        self.http.server_close()
        self.bus.close()


def serve_console(cfg: RuntimeConfig, host: str, port: int, extra_hosts: frozenset[str] = frozenset()) -> None:
    # Ctrl-C or a service manager's stop, taken by this thread alone: blocked here before any thread starts (threads
    # inherit the mask, so the kernel cannot hand the signal to one of the bus's or the server's threads, where it
    # would wait for this thread's next timeout) and received with sigwait, at once
    stops = {signal.SIGINT, signal.SIGTERM}
    signal.pthread_sigmask(signal.SIG_BLOCK, stops)
    server = ConsoleServer(cfg, host, port, extra_hosts)
    print(f"operator console on {server.url} (robot {cfg.robot_id}, runtime at {cfg.zenoh.endpoint}); Ctrl-C quits")
    server.start()
    try:
        signal.sigwait(stops)
    finally:
        server.close()
