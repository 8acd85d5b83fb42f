"""Fuzz the operator console over raw loopback sockets: random methods, paths, versions, Host and Origin
headers, lengths and bodies (random bytes, random JSON, near-valid action bodies). Every case is answered 4xx
(or 200 when it is in fact a good request) within the case bound, never 5xx, a traceback, a hang or a
gigabyte; whatever the console publishes is a valid message; and it keeps answering."""

from __future__ import annotations

import json
import logging
import socket

import pytest
from console_client import Hub, get, read_answer
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from live_nodes import CASE_SECONDS, Tracebacks, bounded_case, free_port, json_values, until

from runtime.config import RuntimeConfig, ZenohConfig
from runtime.messaging.bus import Bus
from runtime.messaging.console.server import ConsoleServer
from runtime.messaging.messages import Command, Confirm, EStop, MessageRefused, decode

pytestmark = pytest.mark.slow

FUZZ = settings(
    max_examples=150, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow], print_blob=True
)
SCHEMAS = {"confirm": Confirm, "command": Command, "estop": EStop}


class Rig:
    def __init__(self) -> None:
        cfg = RuntimeConfig(robot_id="fuzz_console", zenoh=ZenohConfig(endpoint=f"tcp/127.0.0.1:{free_port()}"))
        self.bus = Bus(cfg.zenoh, cfg.robot_id, "listen")
        self.hub = Hub(self.bus)
        self.server = ConsoleServer(cfg, "127.0.0.1", free_port()).start()
        self.port = self.server.http.server_address[1]
        self.watch = Tracebacks()
        logging.getLogger().addHandler(self.watch)
        self.answers: dict[int, int] = {}

    def ask(self, raw: bytes) -> int | None:
        """One case: the status answered, or None when the console closed without an answer."""
        with bounded_case(repr(raw[:200])), socket.create_connection(("127.0.0.1", self.port)) as sock:
            sock.settimeout(CASE_SECONDS - 1)
            sock.sendall(raw)
            sock.shutdown(socket.SHUT_WR)  # the client is done: nothing is waited for
            try:
                status = read_answer(sock, 0.0).status
            except ConnectionError:  # closed without an answer: only for input that is no request at all
                status = None
                assert not raw.strip() or b"\n" not in raw.lstrip(), raw[:300]
        self.answers[status] = self.answers.get(status, 0) + 1
        assert status is None or status < 500, (status, raw[:300])
        assert not self.watch.records, [r.getMessage() for r in self.watch.records]
        return status

    def check_published(self) -> None:
        """Everything the console published is a message the runtime accepts in full."""
        for name, schema in SCHEMAS.items():
            for payload in self.hub.samples[name]:
                try:
                    decode(schema, payload)
                except MessageRefused as e:
                    if "stale" not in str(e):  # (the oldest may have aged past MAX_AGE_S meanwhile)
                        raise AssertionError(f"the console published a bad {name}: {e}: {payload[:200]!r}") from e
            self.hub.samples[name].clear()

    def close(self) -> None:
        logging.getLogger().removeHandler(self.watch)
        self.server.close()
        self.bus.close()


@pytest.fixture(scope="module")
def rig():
    rig = Rig()
    yield rig
    rig.close()


tokens = st.from_regex(r"[!-~]{0,30}", fullmatch=True).map(lambda s: s.replace(":", ""))  # printable ASCII
methods = st.one_of(  # mostly the console's own methods, so that the cases reach its checks
    st.sampled_from(["GET", "POST"] * 3 + ["PUT", "HEAD", "OPTIONS", "DELETE", "PATCH", "TRACE"]), tokens
)
paths = st.one_of(
    st.sampled_from(
        ["/", "/events", "/app.js", "/style.css", "/image/capture", "/image/../../etc/passwd", "*", "http://e/", "//"]
        + [f"/api/{a}" for a in ("estop", "confirm", "run", "abort", "reset", "x", "")]
    ),
    st.from_regex(r"/[!-~]{0,60}", fullmatch=True),
)
versions = st.sampled_from(["HTTP/1.1"] * 6 + ["HTTP/1.0", "HTTP/2.0", "HTTP/0.9", "HTTP/1.1.1", "HTTX/1.1", ""])


@st.composite
def requests(draw, port: int) -> bytes:
    good_host = f"127.0.0.1:{port}"
    host = draw(
        st.sampled_from(
            [good_host] * 4
            + [f"localhost:{port}", f"evil.example:{port}", "127.0.0.1", f"[::1]:{port}", "", None, "x" * 300]
        )
    )
    origins = [None, None, f"http://{good_host}", "http://evil.example", "null", "::", "https://[::1"]
    origin = draw(st.sampled_from(origins))
    headers = [("Host", host), ("Origin", origin), ("X-Goalvla", draw(st.sampled_from([None, "1", "1", "0"])))]
    if draw(st.integers(0, 5)) == 0:
        headers.append(("Host", good_host))  # twice
    extra_names = st.sampled_from(["Transfer-Encoding", "Expect", "Sec-Fetch-Site", "Content-Type", "Connection"])
    for _ in range(draw(st.integers(0, 3))):
        headers.append((draw(st.one_of(extra_names, tokens.filter(bool))), draw(tokens)))
    body = draw(
        st.one_of(
            st.binary(max_size=2000),
            json_values.map(lambda v: json.dumps(v).encode()),
            st.fixed_dictionaries(
                {},
                optional={"plan_id": json_values, "approve": json_values, "instruction": json_values, "x": json_values},
            ).map(lambda d: json.dumps(d).encode()),
        )
    )
    length = draw(
        st.sampled_from(["match", "none", "1000000000", "-1", "abc", "shorter", "longer", "twice", "99999999999999"])
    )
    if length == "match":
        headers.append(("Content-Length", str(len(body))))
    elif length == "shorter":
        headers.append(("Content-Length", str(len(body) + 10)))
    elif length == "longer":
        headers.append(("Content-Length", str(max(0, len(body) - 1))))
    elif length == "twice":
        headers += [("Content-Length", str(len(body)))] * 2
    elif length != "none":
        headers.append(("Content-Length", length))
    head = "".join(f"{k}: {v}\r\n" for k, v in headers if v is not None)
    line = f"{draw(methods)} {draw(paths)} {draw(versions)}".strip()
    return f"{line}\r\n{head}\r\n".encode("latin-1") + body


@FUZZ
@given(data=st.data())
def test_random_requests(rig, data):
    rig.ask(data.draw(requests(rig.port)))
    rig.check_published()


@FUZZ
@given(raw=st.binary(max_size=3000))
def test_random_bytes(rig, raw):
    rig.ask(raw)


def test_the_console_still_answers_and_answered_4xx(rig):
    """(After the families above.) Still serving; and the cases were mostly refusals, each with a 4xx."""
    assert get(rig.port, "/").status == 200
    refused = sum(n for status, n in rig.answers.items() if status is not None and 400 <= status < 500)
    assert refused > 100, rig.answers
    assert until(lambda: rig.server.bridge.page_count() == 0, 10)  # event streams of the cases all ended
