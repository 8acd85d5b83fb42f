"""Garbage-collector pauses kept out of execution.

A full collection walks every tracked object with the GIL held: in a process that has loaded models and run for a
while (hundreds of thousands of objects) that is 0.2-0.6 s, long enough for the deadman to miss the e-stop node's
heartbeats (their callbacks need the GIL) and for the servo stream to stall. While the arm moves, the objects that
existed before it started are frozen out of the collector (gc.freeze: a list splice, no walk); collections then
walk only what execution itself allocates. They are handed back when execution ends.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def collector_pauses_held_off() -> Iterator[None]:
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
