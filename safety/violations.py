"""What the gate reports: every violation with its time, kind, the joints or links involved and the numbers.

A trajectory wrong everywhere would report millions of violations; at most MAX_LISTED_PER_KIND of each kind (the
first found, in time order) are listed and the rest counted (`GateReport.omitted`), so memory stays bounded. Naming
the touching pairs of a colliding configuration costs ten times the check itself, so only the first
MAX_NAMED_CONFIGURATIONS colliding configurations are named pair by pair; each one after them counts as one omitted
violation, which keeps time bounded too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

ViolationKind = Literal[
    "joint_limit",
    "velocity",
    "acceleration",
    "jerk",
    "workspace",
    "keep_out",
    "self_collision",
    "collision",
    "step",
    "tcp_speed",
    "unchecked",  # beyond what the gate checks (samples, collision checks): refused without a verdict
]
MAX_LISTED_PER_KIND = 1000
MAX_NAMED_CONFIGURATIONS = 4 * MAX_LISTED_PER_KIND


@dataclass(frozen=True)
class Violation:
    time_s: float  # from the trajectory start
    kind: ViolationKind
    names: tuple[str, ...]  # joint names, or the two colliding objects, or ("link_tcp",)
    value: float | None = None  # the offending measurement (rad, rad/s, ..., m/s), None for contacts
    limit: float | None = None  # the bound it broke
    detail: str = ""  # one readable sentence

    def to_dict(self) -> dict:
        return {
            "time": round(self.time_s, 6),
            "kind": self.kind,
            "detail": self.detail,
            "names": list(self.names),
            "value": _finite_or_none(self.value),
            "limit": _finite_or_none(self.limit),
        }


def _finite_or_none(x: float | None) -> float | None:
    """JSON has no inf/NaN (an absurd input's derivative overflows); the detail sentence keeps the number."""
    return x if x is None or math.isfinite(x) else None


@dataclass
class ListingBudget:
    """How many more violations of each kind may be listed; those beyond are only counted in `omitted`."""

    per_kind: int = MAX_LISTED_PER_KIND
    omitted: int = 0
    configurations_left: int = MAX_NAMED_CONFIGURATIONS  # colliding configurations whose pairs may still be named
    _listed: dict[str, int] = field(default_factory=dict)

    def take(self, kind: ViolationKind, hits: int) -> int:
        """How many of `hits` new violations of `kind` to list (the first ones)."""
        listed = self._listed.get(kind, 0)
        n = max(0, min(hits, self.per_kind - listed))
        self._listed[kind] = listed + n
        self.omitted += hits - n
        return n


@dataclass(frozen=True)
class GateReport:
    violations: tuple[Violation, ...]
    samples: int  # trajectory samples
    configurations_checked: int  # collision checks including the sub-samples between samples
    seconds: float  # wall time the validation took
    omitted: int = 0  # violations found but not listed (beyond MAX_LISTED_PER_KIND of one kind)

    @property
    def ok(self) -> bool:
        return not self.violations

    def kinds(self) -> set[str]:
        return {v.kind for v in self.violations}

    def reason(self, limit: int = 3) -> str:
        """A short human-readable verdict, e.g. for the operator console and the run record."""
        if self.ok:
            return f"trajectory valid ({self.samples} samples, {self.configurations_checked} configurations checked)"
        first = "; ".join(f"t={v.time_s:.3f} s {v.kind}: {v.detail}" for v in self.violations[:limit])
        total = len(self.violations) + self.omitted
        more = total - min(limit, len(self.violations))
        return f"{total} violations: {first}" + (f"; and {more} more" if more > 0 else "")

    def to_dict(self) -> dict:
        return {
            "ok": self.ok,
            "reason": self.reason(),
            "samples": self.samples,
            "configurations_checked": self.configurations_checked,
            "violations": [v.to_dict() for v in self.violations],
            "violations_omitted": self.omitted,
        }
