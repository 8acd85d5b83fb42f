"""What the gate reports: every violation with its time, kind, the joints or links involved and the numbers."""

from __future__ import annotations

from dataclasses import dataclass
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
]


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
            "value": self.value,
            "limit": self.limit,
        }


@dataclass(frozen=True)
class GateReport:
    violations: tuple[Violation, ...]
    samples: int  # trajectory samples
    configurations_checked: int  # collision checks including the sub-samples between samples
    seconds: float  # wall time the validation took

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
        more = len(self.violations) - limit
        return f"{len(self.violations)} violations: {first}" + (f"; and {more} more" if more > 0 else "")

    def to_dict(self) -> dict:
        return {
            "ok": self.ok,
            "reason": self.reason(),
            "samples": self.samples,
            "configurations_checked": self.configurations_checked,
            "violations": [v.to_dict() for v in self.violations],
        }
