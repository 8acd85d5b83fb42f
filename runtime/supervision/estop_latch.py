"""A lasting e-stop latch: an e-stop outlives the process that saw it.

The state machine latches ESTOPPED for as long as its runtime lives; a one-shot `goalvla run` ends after the stop,
and without this file the next run would start as if nothing had happened. When `runtime.estop_latch_file` is set
(real robots), an e-stop writes the file; a runtime that finds it starts ESTOPPED with the original reason, and
only a reset after someone checked the cell (`goalvla reset`, or Reset on the console) removes it.
"""

from __future__ import annotations

import json
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LatchedStop:
    reason: str
    stamp_s: float  # wall clock (time.time) of the stop

    def describe(self) -> str:
        when = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(self.stamp_s))
        return f"e-stop latched at {when}: {self.reason}"


class EStopLatch:
    """The latch file at `path`; every method is safe to call whether or not it is engaged."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)

    def engage(self, reason: str, stamp_s: float | None = None) -> None:
        """Write the latch (atomically, so a crash mid-write cannot leave a half file that reads as released)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        tmp.write_text(json.dumps({"reason": reason, "stamp_s": time.time() if stamp_s is None else stamp_s}))
        os.replace(tmp, self.path)

    def engaged(self) -> LatchedStop | None:
        """The latched stop, or None. An unreadable file still counts as engaged (any doubt stops)."""
        if not self.path.exists():
            return None
        try:
            data = json.loads(self.path.read_text())
            return LatchedStop(str(data["reason"]), float(data["stamp_s"]))
        except (OSError, ValueError, KeyError, TypeError) as e:
            return LatchedStop(f"latch file {self.path} is unreadable ({e})", self.path.stat().st_mtime)

    def release(self, source: str) -> LatchedStop | None:
        """Remove the latch; returns what was latched (None if nothing was)."""
        latched = self.engaged()
        if latched is not None:
            self.path.unlink(missing_ok=True)
            log.warning("e-stop latch released by %s (%s)", source, latched.describe())
        return latched
