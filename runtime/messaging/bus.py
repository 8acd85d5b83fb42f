"""One Zenoh session per node, configured from the profile, with typed publish/subscribe on top.

The runtime node listens on `runtime.zenoh.endpoint`; console and e-stop nodes connect to it (they retry in the
background until it is up). Scouting (multicast and gossip) is always off, so nothing is discovered or reached
that the profile does not name. Off the loopback the endpoint must be `tls/...` with certificates (mutual TLS
by default) and the profile may add a Zenoh access-control block (see configs/lab.yaml).
"""

from __future__ import annotations

import contextlib
import json
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Literal

import zenoh

from runtime.config import ZenohConfig
from runtime.messaging.messages import Keys, Message, MessageRefused, decode, printable
from runtime.messaging.throttle import Throttle

log = logging.getLogger(__name__)

Role = Literal["listen", "connect"]
URGENT_SUFFIXES = ("/estop", "/command", "/confirm")  # sent at real-time priority, never dropped, not batched


def session_config(cfg: ZenohConfig, role: Role) -> dict:
    """The Zenoh session configuration (as JSON) for a node of the given role."""
    conf: dict = {
        "mode": "peer",
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
    }
    if role == "listen":
        conf["listen"] = {"endpoints": [cfg.endpoint]}
    else:
        conf["connect"] = {"endpoints": [cfg.endpoint], "timeout_ms": -1, "exit_on_failure": False}
        conf["listen"] = {"endpoints": []}
    if cfg.tls is not None:
        tls = {"root_ca_certificate": str(cfg.tls.root_ca_certificate), "enable_mtls": cfg.tls.mutual}
        side = "listen" if role == "listen" else "connect"
        tls[f"{side}_certificate"] = str(cfg.tls.certificate)
        tls[f"{side}_private_key"] = str(cfg.tls.private_key)
        conf["transport"] = {"link": {"tls": tls}}
    if cfg.access_control is not None:
        conf["access_control"] = cfg.access_control
    return conf


class Bus:
    """A node's Zenoh session. Callbacks run on Zenoh's threads: keep them short and never block in them."""

    def __init__(self, cfg: ZenohConfig, robot_id: str, role: Role) -> None:
        self.keys = Keys(robot_id)
        self.role = role
        try:
            self.session = zenoh.open(zenoh.Config.from_json5(json.dumps(session_config(cfg, role))))
        except zenoh.ZError as e:
            raise ConnectionError(f"zenoh session ({role} {cfg.endpoint}) could not open: {e}") from None
        self._publishers: dict[str, zenoh.Publisher] = {}
        self._lock = threading.Lock()
        self._declared: list = []
        self.handled: Counter[str] = Counter()  # samples handled per subscribed key expression (refused included)
        self.refused: Counter[str] = Counter()  # of which refused
        self._refusal_log = Throttle(per_period=5, period_s=1.0)

    def _publisher(self, key: str) -> zenoh.Publisher:
        with self._lock:
            pub = self._publishers.get(key)
            if pub is None:
                urgent = key.endswith(URGENT_SUFFIXES)
                pub = self.session.declare_publisher(
                    key,
                    priority=zenoh.Priority.REAL_TIME if urgent else zenoh.Priority.DATA,
                    congestion_control=zenoh.CongestionControl.BLOCK if urgent else zenoh.CongestionControl.DROP,
                    express=urgent,
                )
                self._publishers[key] = pub
            return pub

    def publish(self, key: str, message: Message | bytes) -> None:
        payload = message if isinstance(message, bytes) else message.encode()
        self._publisher(key).put(payload)

    def subscribe(self, key: str, schema: type[Message], callback: Callable[[str, Message], None]) -> None:
        """Deliver checked messages (runtime.messaging.messages.decode); anything else is refused and logged with
        its reason (a flood of refusals is logged a few times a second, with the count)."""

        def deliver(sample_key: str, raw: bytes) -> None:
            try:
                message = decode(schema, raw, time.time())
            except MessageRefused as e:
                self.refuse(key, sample_key, f"{schema.__name__}: {e}")
                return
            callback(sample_key, message)

        self.subscribe_bytes(key, deliver)

    def subscribe_bytes(self, key: str, callback: Callable[[str, bytes], None], max_bytes: int | None = None) -> None:
        """callback(sample key, payload) for every sample; one larger than `max_bytes` is refused unread."""

        def handler(sample: zenoh.Sample) -> None:
            sample_key = str(sample.key_expr)
            try:
                size = len(sample.payload)
                if max_bytes is not None and size > max_bytes:
                    self.refuse(key, sample_key, f"payload of {size} bytes (limit {max_bytes})")
                else:
                    callback(sample_key, sample.payload.to_bytes())
            except Exception:  # a bug in a handler must not take Zenoh's thread down with it
                log.exception("handler for %s failed", sample_key)
            finally:
                with self._lock:
                    self.handled[key] += 1

        self._declared.append(self.session.declare_subscriber(key, handler))

    def refuse(self, key: str, sample_key: str, reason: str) -> None:
        """Count and log (throttled) a sample refused on `key`."""
        with self._lock:
            self.refused[key] += 1
        self._refusal_log.tell(f"refused a sample on {printable(sample_key, 120)}: {reason}", log.warning)

    def declare_token(self, key: str) -> None:
        """A liveliness token: it vanishes for every watcher when this node closes or its link drops."""
        self._declared.append(self.session.liveliness().declare_token(key))

    def watch_liveliness(self, key: str, callback: Callable[[str, bool], None]) -> None:
        """callback(token key, alive) for tokens matching `key`, including those already present."""

        def handler(sample: zenoh.Sample) -> None:
            callback(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

        self._declared.append(self.session.liveliness().declare_subscriber(key, handler, history=True))

    def close(self) -> None:
        for entity in reversed(self._declared):
            with contextlib.suppress(zenoh.ZError):
                entity.undeclare()
        self._declared.clear()
        self.session.close()

    def __enter__(self) -> Bus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
