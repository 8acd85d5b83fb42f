"""`goalvla console`: serves the operator page and bridges it to Zenoh.

Downstream, one server-sent-events stream per page carries status, events, plan summaries, throttled joint
states and "image updated" notices (the page then fetches /image/<name>). Upstream, small JSON POSTs become
Zenoh messages: command (run, abort, reset), confirm (with the plan id the page shows) and estop. POSTs must
carry the X-Goalvla header (a cross-site page cannot add it without a CORS preflight, which is never granted).
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from importlib import resources

from runtime.config import RuntimeConfig
from runtime.messaging.bus import Bus
from runtime.messaging.messages import Command, Confirm, EStop, Event, Heartbeat, JointStateMsg, PlanSummary, Status

log = logging.getLogger(__name__)

JOINT_STATE_PAGE_HZ = 10.0
KEEPALIVE_S = 1.0
STATIC = {
    "/": ("index.html", "text/html"),
    "/app.js": ("app.js", "text/javascript"),
    "/style.css": ("style.css", "text/css"),
}


class Bridge:
    """Latest of everything the runtime publishes, fanned out to connected pages."""

    def __init__(self, bus: Bus, node: str = "console") -> None:
        self.bus, self.node = bus, node
        self._lock = threading.Lock()
        self._clients: list[queue.Queue] = []
        self.latest: dict[str, dict] = {}
        self.images: dict[str, tuple[int, bytes]] = {}
        self._last_joint_push = 0.0
        keys = bus.keys
        bus.subscribe(keys.status, Status, lambda k, m: self._push("status", m.model_dump()))
        bus.subscribe(keys.events, Event, lambda k, m: self._push("event", m.model_dump(), keep=False))
        bus.subscribe(keys.plan, PlanSummary, lambda k, m: self._push("plan", m.model_dump()))
        bus.subscribe(keys.joint_state, JointStateMsg, self._on_joint_state)
        bus.subscribe_bytes(f"{keys.images}/*", self._on_image)
        self._seq = 0
        self._stop = threading.Event()
        threading.Thread(target=self._heartbeat, name="console-heartbeat", daemon=True).start()

    def _push(self, kind: str, data: dict, keep: bool = True) -> None:
        item = {"type": kind, "data": data}
        with self._lock:
            if keep:
                self.latest[kind] = item
            clients = list(self._clients)
        for q in clients:
            q.put(item)

    def _on_joint_state(self, _key: str, msg: JointStateMsg) -> None:
        now = time.monotonic()
        if now - self._last_joint_push >= 1.0 / JOINT_STATE_PAGE_HZ:
            self._last_joint_push = now
            self._push("joint_state", msg.model_dump())

    def _on_image(self, key: str, payload: bytes) -> None:
        name = key.rsplit("/", 1)[-1]
        with self._lock:
            version = self.images.get(name, (0, b""))[0] + 1
            self.images[name] = (version, payload)
        self._push("image", {"name": name, "version": version}, keep=False)

    def attach(self) -> queue.Queue:
        q: queue.Queue = queue.Queue(maxsize=1000)
        with self._lock:
            self._clients.append(q)
            for item in self.latest.values():
                q.put(item)
            for name, (version, _) in self.images.items():
                q.put({"type": "image", "data": {"name": name, "version": version}})
        return q

    def detach(self, q: queue.Queue) -> None:
        with self._lock:
            if q in self._clients:
                self._clients.remove(q)

    def _heartbeat(self) -> None:
        """The console's own presence (kind console: shown to operators, not a deadman for execution)."""
        key = self.bus.keys.heartbeat_of(self.node)
        while not self._stop.wait(0.5):
            self._seq += 1
            self.bus.publish(key, Heartbeat(stamp_s=time.time(), node=self.node, kind="console", seq=self._seq))

    def close(self) -> None:
        self._stop.set()

    # -- operator actions ---------------------------------------------------------------------------------
    def act(self, action: str, body: dict) -> str:
        keys, now = self.bus.keys, time.time()
        if action == "estop":
            self.bus.publish(keys.estop, EStop(stamp_s=now, source=self.node, reason="console E-STOP button"))
        elif action == "confirm":
            plan_id = str(body.get("plan_id", ""))
            if not plan_id:
                raise ValueError("confirm needs the plan_id shown on the page")
            self.bus.publish(
                keys.confirm,
                Confirm(stamp_s=now, plan_id=plan_id, source=self.node, approve=bool(body.get("approve", True))),
            )
        elif action in ("run", "abort", "reset"):
            instruction = str(body.get("instruction", "")).strip()
            if action == "run" and not instruction:
                raise ValueError("run needs an instruction")
            self.bus.publish(
                keys.command, Command(stamp_s=now, action=action, instruction=instruction, source=self.node)
            )
        else:
            raise KeyError(action)
        return action


def make_handler(bridge: Bridge):
    class Handler(BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def log_message(self, fmt: str, *args) -> None:
            log.debug("console http: " + fmt, *args)

        def _send(self, status: int, body: bytes, content_type: str, extra: dict | None = None) -> None:
            self.send_response(status)
            self.send_header("Content-Type", content_type)
            self.send_header("Content-Length", str(len(body)))
            self.send_header("Cache-Control", "no-store")
            for k, v in (extra or {}).items():
                self.send_header(k, v)
            self.end_headers()
            self.wfile.write(body)

        def do_GET(self) -> None:
            path = self.path.split("?", 1)[0]
            if path in STATIC:
                name, ctype = STATIC[path]
                body = resources.files("runtime.messaging.console").joinpath("static", name).read_bytes()
                self._send(HTTPStatus.OK, body, f"{ctype}; charset=utf-8")
            elif path.startswith("/image/"):
                _version, data = bridge.images.get(path.removeprefix("/image/"), (0, b""))
                if not data:
                    self._send(HTTPStatus.NOT_FOUND, b"no such image yet", "text/plain")
                else:
                    self._send(HTTPStatus.OK, data, "image/jpeg")
            elif path == "/events":
                self._stream()
            else:
                self._send(HTTPStatus.NOT_FOUND, b"not found", "text/plain")

        def _stream(self) -> None:
            self.send_response(HTTPStatus.OK)
            self.send_header("Content-Type", "text/event-stream")
            self.send_header("Cache-Control", "no-store")
            self.end_headers()
            q = bridge.attach()
            try:
                while True:
                    try:
                        item = q.get(timeout=KEEPALIVE_S)
                        self.wfile.write(f"data: {json.dumps(item)}\n\n".encode())
                    except queue.Empty:
                        self.wfile.write(b": keep-alive\n\n")
                    self.wfile.flush()
            except (BrokenPipeError, ConnectionResetError):
                pass
            finally:
                bridge.detach(q)
                self.close_connection = True

        def do_POST(self) -> None:
            if self.headers.get("X-Goalvla") != "1":
                self._send(HTTPStatus.FORBIDDEN, b"missing X-Goalvla header", "text/plain")
                return
            action = self.path.removeprefix("/api/")
            try:
                length = int(self.headers.get("Content-Length", "0"))
                body = json.loads(self.rfile.read(length) or b"{}")
                if not isinstance(body, dict):
                    raise ValueError("body must be a JSON object")
                bridge.act(action, body)
            except KeyError:
                self._send(HTTPStatus.NOT_FOUND, b'{"error": "unknown action"}', "application/json")
            except ValueError as e:
                self._send(HTTPStatus.BAD_REQUEST, json.dumps({"error": str(e)}).encode(), "application/json")
            else:
                self._send(HTTPStatus.OK, json.dumps({"ok": True, "action": action}).encode(), "application/json")

    return Handler


class ConsoleServer:
    """The bridge plus its HTTP server; `start()` serves on a background thread (tests), `serve_forever` blocks."""

    def __init__(self, cfg: RuntimeConfig, host: str = "127.0.0.1", port: int = 8080) -> None:
        self.bus = Bus(cfg.zenoh, cfg.robot_id, "connect")
        self.bridge = Bridge(self.bus)
        self.http = ThreadingHTTPServer((host, port), make_handler(self.bridge))
        self.http.daemon_threads = True
        self.url = f"http://{host}:{self.http.server_address[1]}/"

    def start(self) -> ConsoleServer:
        threading.Thread(target=self.http.serve_forever, name="console-http", daemon=True).start()
        return self

    def close(self) -> None:
        self.http.shutdown()
        self.http.server_close()
        self.bridge.close()
        self.bus.close()


def serve_console(cfg: RuntimeConfig, host: str, port: int) -> None:
    server = ConsoleServer(cfg, host, port)
    print(f"operator console on {server.url} (robot {cfg.robot_id}, runtime at {cfg.zenoh.endpoint}); Ctrl-C quits")
    try:
        server.http.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.close()
