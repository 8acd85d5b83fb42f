"""What the bus and console fuzz files share: per-case bounds on a live node, a watch for tracebacks, loopback
ports, and JSON values of every shape.

The cases exercise servers and Zenoh callbacks running on their own threads, so they run in-process and are
measured rather than forked: the kernel's peak-RSS counter (VmHWM) is reset before each case (/proc/self/
clear_refs) and read after it, so a case that allocates a gigabyte fails even if it frees it again; time is the
case's own wait, bounded by the caller's timeouts (a hang fails the case, it never stalls the suite).
"""

from __future__ import annotations

import logging
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from hypothesis import strategies as st

CASE_MEMORY_BYTES = 1 << 30  # the bound: under 1 GB per case
CASE_SECONDS = 5.0  # a case is milliseconds; this is a hang, on a loaded machine


def _status_kb(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field}")


@dataclass
class CaseCost:
    seconds: float = 0.0
    peak_growth_bytes: int = 0


@contextmanager
def bounded_case(what: str) -> Iterator[CaseCost]:
    """Measure the case in the block; AssertionError when it took over CASE_SECONDS or CASE_MEMORY_BYTES."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # reset VmHWM to the current RSS
    start_kb = _status_kb("VmRSS")
    t0 = time.monotonic()
    cost = CaseCost()
    yield cost
    cost.seconds = time.monotonic() - t0
    cost.peak_growth_bytes = (_status_kb("VmHWM") - start_kb) * 1024
    assert cost.seconds < CASE_SECONDS, f"{what}: took {cost.seconds:.1f} s"
    assert cost.peak_growth_bytes < CASE_MEMORY_BYTES, f"{what}: peak memory grew {cost.peak_growth_bytes >> 20} MB"


class Tracebacks(logging.Handler):
    """Log records that carry a traceback or are errors: none may come from bad input."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        if record.exc_info or record.levelno >= logging.ERROR:
            self.records.append(record)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def until(predicate, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.001)  # polling the handled counter
    return True


scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0, -1, 1e308, -1e308, 5e-324, 10**19, 2**63]),
    st.text(max_size=20),
)
json_values = st.recursive(
    scalars,
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=30,
)
