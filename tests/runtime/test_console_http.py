"""The console against hostile or broken HTTP clients, on raw loopback sockets: wrong Host or Origin, bad bodies
and lengths, loose JSON types, stalled event streams, floods, disconnects and Ctrl-C."""

from __future__ import annotations

import json
import logging
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest
from console_client import Hub, get, post, read_answer, send
from runtime_helpers import free_port, wait_for

from runtime.messaging.bus import Bus
from runtime.messaging.console.server import BODY_TIMEOUT_S, MAX_BODY_BYTES, MAX_CONNECTIONS, ConsoleServer
from runtime.messaging.messages import Status


@pytest.fixture
def console(runtime_cfg, caplog):
    caplog.set_level(logging.DEBUG, logger="runtime.messaging.console")
    with Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "listen") as bus:
        hub = Hub(bus)
        server = ConsoleServer(runtime_cfg, "127.0.0.1", free_port()).start()
        port = server.http.server_address[1]
        try:
            assert wait_for(lambda: _fence(port, hub), 10, 0.05), "console and hub never connected"
            yield port, hub, server
        finally:
            server.close()
    tracebacks = [r for r in caplog.records if r.exc_info or r.levelno >= logging.ERROR]
    assert not tracebacks, [r.getMessage() for r in tracebacks]


def _fence(port: int, hub: Hub, plan_id: str = "fence") -> bool:
    """A good confirm, published after whatever was sent before it; True once it arrived."""
    assert post(port, "confirm", json.dumps({"plan_id": plan_id}).encode()).status == 200
    return wait_for(lambda: any(m["plan_id"] == plan_id for m in hub.messages("confirm")), 0.5)


def confirms_after(port: int, hub: Hub, plan_id: str) -> list[dict]:
    """The confirms published up to a fence sent now (so what a bad request published has arrived too)."""
    before = len(hub.messages("confirm"))
    assert wait_for(lambda: _fence(port, hub, plan_id), 5, 0.05)
    return [m for m in hub.messages("confirm")[before:] if m["plan_id"] != plan_id]


def test_a_good_confirm_is_published_typed(console):
    port, hub, _ = console
    answer = post(port, "confirm", b'{"plan_id": "p1", "approve": false}')
    assert answer.status == 200 and answer.json() == {"ok": True, "action": "confirm"}
    assert (
        answer.headers["x-frame-options"] == "DENY"
        and "frame-ancestors 'none'" in answer.headers["content-security-policy"]
    )
    assert wait_for(lambda: [(m["plan_id"], m["approve"]) for m in hub.messages("confirm")][-1] == ("p1", False))


@pytest.mark.parametrize(
    ("headers", "status", "says"),
    [
        ({"Origin": "http://evil.example"}, 403, "Origin http://evil.example is not this console"),
        ({"Origin": "null"}, 403, "Origin null"),
        ({"Host": "evil.example:{port}", "Origin": "http://evil.example:{port}"}, 421, "Host evil.example"),
        ({"Host": "127.0.0.1:1"}, 421, "is not"),
        ({"Host": None}, 400, "exactly one Host header"),
        ({"Sec-Fetch-Site": "cross-site"}, 403, "cross-site"),
        ({"X-Goalvla": None}, 403, "missing X-Goalvla header"),
    ],
)
def test_foreign_pages_and_rebound_names_are_refused(console, headers, status, says):
    port, hub, _ = console
    headers = {k: (v.format(port=port) if v else v) for k, v in headers.items()}
    answer = post(port, "confirm", b'{"plan_id": "evil"}', headers=headers)
    assert answer.status == status and says in answer.json()["error"], answer
    assert confirms_after(port, hub, "f2") == []


def test_dns_rebinding_cannot_read_the_event_stream(console):
    port, _, _ = console
    assert get(port, "/events", host=f"evil.example:{port}").status == 421
    assert get(port, "/", host=f"evil.example:{port}").status == 421
    assert get(port, "/", host=f"localhost:{port}").status == 200


@pytest.mark.parametrize(
    ("body", "says"),
    [
        (b'{"plan_id": "abc", "approve": "false"}', "approve: input should be a valid boolean"),
        (b'{"plan_id": 5}', "plan_id: input should be a valid string"),
        (b'{"plan_id": "abc", "extra": 1}', "extra: extra inputs are not permitted"),
        (b'{"plan_id": "abc", "plan_id": "def"}', "appears twice"),
        (b'["plan_id"]', "not a JSON object"),
        (b'{"plan_id": NaN}', "NaN is not a JSON number"),
        (b"[" * 8000 + b"]" * 8000, "nested too deeply"),
        (b"\xff\xfe", "not UTF-8"),
        (b"plan please", "not JSON"),
    ],
)
def test_loose_or_malformed_json_is_a_400(console, body, says):
    port, hub, _ = console
    answer = post(port, "confirm", body)
    assert answer.status == 400 and says in answer.json()["error"], answer
    assert confirms_after(port, hub, "f3") == []


def test_run_needs_a_bounded_instruction(console):
    port, _, _ = console
    assert "instruction: field required" in post(port, "run", b"{}").json()["error"]
    assert post(port, "run", b'{"instruction": "   "}').status == 400
    assert post(port, "run", json.dumps({"instruction": "x" * 1001}).encode()).status == 400
    assert post(port, "abort", b'{"now": true}').status == 400
    assert post(port, "fly", b"{}").status == 404


@pytest.mark.parametrize(
    ("length", "sent", "status", "says"),
    [
        ("1000000000", b"{}", 413, "body of 1000000000 bytes"),
        (str(50 * 1024 * 1024), b"{" * 4096, 413, "limit"),
        ("-1", b"{}", 400, "must be a number of bytes"),
        ("abc", b"{}", 400, "must be a number of bytes"),
        ("1e3", b"{}", 400, "must be a number of bytes"),
        ("99999999999999999999999", b"{}", 400, "must be a number of bytes"),
    ],
)
def test_bad_content_lengths_are_answered_at_once(console, length, sent, status, says):
    port, hub, _ = console
    answer = post(port, "confirm", sent, headers={"Content-Length": length})
    assert answer.status == status and says in answer.json()["error"], answer
    assert answer.seconds < 1.0 and answer.headers.get("connection") == "close"
    assert confirms_after(port, hub, "f4") == []


def test_a_body_shorter_than_its_length_is_not_waited_for(console):
    port, _, _ = console
    raw = f"POST /api/confirm HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nX-Goalvla: 1\r\nContent-Length: 100\r\n\r\n{{}}"
    with socket.create_connection(("127.0.0.1", port), timeout=10) as held_open:  # the client never sends the rest
        t0 = time.monotonic()
        held_open.sendall(raw.encode())
        answer = read_answer(held_open, t0)
    assert answer.status == 400 and "shorter than its Content-Length 100" in answer.json()["error"]
    assert answer.seconds < BODY_TIMEOUT_S + 1.0
    closed_early = send(port, raw.encode(), shut_write=True)  # a client that says it is done: answered at once
    assert closed_early.status == 400 and closed_early.seconds < 1.0


def test_chunked_and_oversized_bodies_are_refused(console):
    port, _, _ = console
    chunked = post(port, "confirm", b"5\r\nhello\r\n0\r\n\r\n", headers={"Transfer-Encoding": "chunked"})
    assert chunked.status == 411
    assert post(port, "confirm", b"x" * (MAX_BODY_BYTES + 1)).status == 413


def test_estop_is_sent_whatever_its_body(console):
    port, hub, _ = console
    assert post(port, "estop", b"").status == 200
    refused = post(port, "estop", b"", headers={"Content-Length": "1000000000"})
    assert refused.status == 413 and refused.json()["estop_sent"] is True
    assert post(port, "estop", b"garbage").json()["estop_sent"] is True
    assert wait_for(lambda: len(hub.messages("estop")) == 3)
    assert all(m["reason"] == "console E-STOP button" for m in hub.messages("estop"))


def test_http_oddities_are_4xx(console):
    port, _, _ = console
    host = f"Host: 127.0.0.1:{port}\r\n"
    assert send(port, f"PUT / HTTP/1.1\r\n{host}\r\n".encode()).status == 405
    assert send(port, f"BREW /pot HTTP/1.1\r\n{host}\r\n".encode()).status == 405
    assert send(port, f"GET / HTTP/2.0\r\n{host}\r\n".encode()).status == 400
    assert send(port, b"GARBAGE\r\n\r\n").status == 400
    assert send(port, b"GET /\r\n\r\n").status == 400  # HTTP/0.9: answered with a status line all the same
    assert send(port, f"GET / HTTP/0.9\r\n{host}\r\n".encode()).status == 400
    assert send(port, b"GET /" + b"a" * 70000 + b" HTTP/1.1\r\n\r\n").status == 414
    assert send(port, f"GET /nope HTTP/1.1\r\n{host}\r\n".encode()).status == 404
    assert send(port, b"\n\x00\n", shut_write=True).status == 400  # a blank line, then no request line: answered
    assert send(port, f"\r\n\r\nGET /nope HTTP/1.1\r\n{host}\r\n".encode()).status == 404  # blank lines skipped
    assert send(port, b"\r\n" * 40000 + b"GET / HTTP/1.1\r\n\r\n").status == 400  # but not without end


def open_stream(port: int, rcvbuf: int | None = None) -> socket.socket:
    sock = socket.socket()
    if rcvbuf is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(10)
    sock.connect(("127.0.0.1", port))
    sock.sendall(f"GET /events HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
    return sock


def read_until(sock: socket.socket, needle: bytes, timeout_s: float = 10.0) -> bytes:
    data, deadline = b"", time.monotonic() + timeout_s
    while needle not in data:
        sock.settimeout(max(0.01, deadline - time.monotonic()))
        try:
            chunk = sock.recv(65536)
        except TimeoutError:
            break
        if not chunk:
            break
        data += chunk
    return data


def follow(port: int, sock: socket.socket, needle: bytes, timeout_s: float = 20.0) -> bool:
    """Read a page's stream until `needle`, reconnecting like a browser's EventSource when the console drops it."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        data = read_until(sock, needle, deadline - time.monotonic())
        sock.close()
        if needle in data:
            return True
        sock = open_stream(port)  # dropped (it fell behind): reconnect, the latest state comes first
    return False


def test_a_stalled_page_is_dropped_and_holds_no_one(console):
    port, hub, server = console
    live = open_stream(port)
    stalled = open_stream(port, rcvbuf=4096)  # reads nothing from here on
    assert b"retry: 1000" in read_until(live, b"retry: 1000")
    padding = "x" * 4000  # 32 MB in all: more than any socket buffers between here and a stalled client
    for i in range(8000):
        hub.bus.publish(hub.bus.keys.status, Status(stamp_s=time.time(), state="IDLE", reason=f"flood {i} {padding}"))
    done = threading.Event()

    def republish() -> None:  # like the runtime's status publisher (status samples may be dropped on congestion)
        while not done.wait(0.5):
            hub.bus.publish(hub.bus.keys.status, Status(stamp_s=time.time(), state="IDLE", reason="the last one"))

    threading.Thread(target=republish, daemon=True).start()
    assert follow(port, open_stream(port), b"the last one"), "a page opened after the flood never got the state"
    assert follow(port, live, b"the last one"), "a page open during the flood never got the state"
    assert get(port, "/").status == 200
    assert wait_for(lambda: server.bridge.page_count() == 0, 10), "the stalled page was never dropped"
    done.set()
    stalled.close()


def test_connections_are_capped_and_freed(console):
    port, _, _ = console
    idle = [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(MAX_CONNECTIONS + 1)]
    try:
        over = read_answer(idle[-1], time.monotonic())
        assert over.status == 429
    finally:
        for sock in idle:
            sock.close()
    assert wait_for(lambda: get(port, "/").status == 200, 5, 0.05)


def test_disconnects_leave_no_traceback(console):
    port, _, _ = console
    for _ in range(20):
        with socket.create_connection(("127.0.0.1", port)) as sock:  # ask, then leave without reading
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")  # reset
            sock.sendall(f"GET /app.js HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())
        stream = open_stream(port)
        read_until(stream, b"retry")
        stream.close()
    assert get(port, "/").status == 200  # (the fixture checks the log for tracebacks)


@pytest.mark.slow
def test_ctrl_c_ends_the_console_within_a_second(runtime_cfg, tmp_path, sim_config_path):
    profile = tmp_path / "p.yaml"
    profile.write_text(
        f"include: {sim_config_path}\nruntime: {{robot_id: {runtime_cfg.robot_id}, "
        f"zenoh: {{endpoint: '{runtime_cfg.zenoh.endpoint}'}}}}\n"
    )
    port = free_port()
    cmd = [sys.executable, "-m", "runtime.commands.cli", "console", "--config", str(profile), "--port", str(port)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert wait_for(lambda: _answers(port), 60, 0.1), "the console did not come up"
        streams = [open_stream(port), open_stream(port, rcvbuf=4096)]
        read_until(streams[0], b"retry")
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
        took = time.monotonic() - t0
        _, err = proc.communicate()
    finally:
        proc.kill()
    assert took < 1.0, f"took {took:.2f} s"
    assert proc.returncode == 0 and "Traceback" not in err, err


def _answers(port: int) -> bool:
    try:
        return get(port, "/").status == 200
    except OSError:
        return False
