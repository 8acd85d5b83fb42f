"""Which requests the console answers: Host and Origin must name the address it serves.

A page from another site cannot press the console's buttons: POSTs need the X-Goalvla header (never granted
to a cross-site request, there is no CORS preflight answer), and a browser's Origin must be this console. A
hostile name that resolves to this machine (DNS rebinding) is caught by Host: only the IP literal the request
arrived on (and `localhost` on the loopback), or a name the operator allowed, with the served port.
"""

from __future__ import annotations

import ipaddress
from dataclasses import dataclass
from email.message import Message
from http import HTTPStatus
from urllib.parse import urlsplit

from runtime.messaging.messages import printable


@dataclass(frozen=True)
class Refusal:
    status: HTTPStatus
    reason: str


def _split_host(value: str) -> tuple[str, int | None] | None:
    """('host', port or None) of a Host header value; None if it is not one."""
    value = value.strip().lower()
    if value.startswith("["):
        end = value.find("]")
        if end < 0:
            return None
        host, rest = value[1:end], value[end + 1 :]
    else:
        host, sep, port = value.partition(":")
        rest = f":{port}" if sep else ""
    if rest and not (rest.startswith(":") and rest[1:].isdigit() and len(rest) <= 6):
        return None
    return host.rstrip("."), int(rest[1:]) if rest else None


def _is_loopback(ip: str) -> bool:
    try:
        return ipaddress.ip_address(ip).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class Guard:
    port: int  # the port the console serves
    extra_hosts: frozenset[str] = frozenset()  # names the operator allowed (e.g. a lab host name)

    def names(self, local_ip: str) -> set[str]:
        """The host names a request that arrived on local_ip may use."""
        ip = local_ip.removeprefix("::ffff:") if "." in local_ip else local_ip
        names = {ip.lower(), *self.extra_hosts}
        if _is_loopback(ip):
            names.add("localhost")
        return names

    def _ours(self, host: str, port: int | None, default_port: int, local_ip: str) -> bool:
        return host in self.names(local_ip) and (port if port is not None else default_port) == self.port

    def check(self, headers: Message, local_ip: str) -> Refusal | None:
        hosts = headers.get_all("Host") or []
        if len(hosts) != 1:
            return Refusal(HTTPStatus.BAD_REQUEST, "exactly one Host header is needed")
        split = _split_host(hosts[0])
        if split is None or not self._ours(*split, 80, local_ip):
            served = ", ".join(f"{n}:{self.port}" for n in sorted(self.names(local_ip)))
            return Refusal(HTTPStatus.MISDIRECTED_REQUEST, f"Host {printable(hosts[0], 80)} is not {served}")
        origins = headers.get_all("Origin") or []
        if len(origins) > 1:
            return Refusal(HTTPStatus.FORBIDDEN, "more than one Origin header")
        if origins:
            try:
                origin = urlsplit(origins[0].strip())
                split = _split_host(origin.netloc) if origin.scheme in ("http", "https") else None
            except ValueError:  # not a URL at all
                split = None
            default = 443 if split is not None and origin.scheme == "https" else 80
            if split is None or origin.path or not self._ours(*split, default, local_ip):
                return Refusal(HTTPStatus.FORBIDDEN, f"Origin {printable(origins[0], 80)} is not this console")
        if headers.get("Sec-Fetch-Site", "").strip().lower() == "cross-site":
            return Refusal(HTTPStatus.FORBIDDEN, "a cross-site request")
        return None
