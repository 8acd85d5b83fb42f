"""One run's outcome as a campaign counts it (result.json in its run folder, read from its summary.json), and the
campaign's table: per task and per action, how many runs were verified, really done by the simulator's truth,
false successes and false failures, where failures started, and the median time.
"""

from __future__ import annotations

import statistics
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict

from runtime.campaign.cases import Case
from runtime.campaign.truth import judge
from runtime.run.summary import RunSummary

RESULT_FILE = "result.json"
Status = Literal["DONE", "FAILED", "ESTOPPED", "REFUSED"]
# how a run ends when this machine, not the run, failed: the simulated robot's state report or the e-stop node's
# heartbeat starved by other work (the real arm and pendant run on their own computers), a capture past its budget
LOAD_FAULTS = ("stale joint state", "the state report stalled", "no e-stop node heartbeat", "CAPTURING took too long")


def is_load_fault(status: str, reason: str) -> bool:
    return status != "DONE" and any(fault in reason for fault in LOAD_FAULTS)


class CaseResult(BaseModel):
    model_config = ConfigDict(extra="forbid")

    case: Case
    status: Status  # REFUSED: the run did not start (a sentence outside the grammar, a scene that cannot be placed)
    reason: str
    failed_in: str | None  # the state the run failed or stopped in (lower case), None when verified
    wall_s: float | None  # the run's own wall time (summary.json: from its start until its record is written)
    run_s: float | None = None  # the whole run as the worker saw it: devices, the run, its plots and recording
    recording_s: float | None = None  # of which writing run.rrd (summary.json's record_seconds)
    verified: bool  # the run's verdict: DONE
    truly_done: bool | None  # the simulator's: None when it cannot tell (runtime.campaign.truth)
    jitter_p99_s: float | None  # worst streaming jitter p99 over the run's phases
    worker: str = ""  # where it ran (host:pid)
    load_fault: bool = False  # stopped by this machine's load (LOAD_FAULTS), not by the run
    ran_again_after: str | None = None  # the reason an earlier attempt stopped for this machine's load
    load_1min: float | None = None  # the machine's load average while it ran

    @classmethod
    def of(cls, case: Case, summary: RunSummary, worker: str = "", run_s: float | None = None) -> CaseResult:
        failed_in = next((t.previous.lower() for t in summary.transitions if t.state in ("FAILED", "ESTOPPED")), None)
        jitter = [p.jitter_p99_s for p in summary.execution if p.ticks > 0]
        return cls(
            case=case,
            status=summary.status if summary.status != "RUNNING" else "FAILED",
            reason=summary.reason,
            failed_in=failed_in,
            wall_s=summary.wall_s,
            verified=summary.status == "DONE",
            truly_done=judge(case, summary),
            jitter_p99_s=max(jitter) if jitter else None,
            worker=worker,
            run_s=None if run_s is None else round(run_s, 3),
            recording_s=summary.record_seconds.get("recording"),
            load_fault=is_load_fault(summary.status, summary.reason),
        )

    @classmethod
    def refused(cls, case: Case, reason: str, worker: str = "") -> CaseResult:
        return cls(
            case=case,
            status="REFUSED",
            reason=reason,
            failed_in="before start",
            wall_s=None,
            verified=False,
            truly_done=None,
            jitter_p99_s=None,
            worker=worker,
        )

    @classmethod
    def read(cls, run_dir: Path) -> CaseResult | None:
        path = run_dir / RESULT_FILE
        return cls.model_validate_json(path.read_text()) if path.is_file() else None


class Row(BaseModel):
    """One line of the table: a group of runs (a task, an action, or all)."""

    group: str
    runs: int
    verified: int
    success_rate: float
    truly_done: int
    false_successes: int  # verified, but the simulator says not done
    false_failures: int  # not verified, but the simulator says done
    truth_unknown: int
    refused_before_start: int
    load_faults: int  # stopped by this machine's load (after a second attempt where the worker made one)
    failed_in: dict[str, int]  # where the failures started: the state the run ended in
    median_wall_s: float | None  # over the runs that started

    @classmethod
    def of(cls, group: str, results: list[CaseResult]) -> Row:
        started = [r for r in results if r.status != "REFUSED"]
        walls = [r.wall_s for r in started if r.wall_s is not None]
        verified = sum(r.verified for r in results)
        return cls(
            group=group,
            runs=len(results),
            verified=verified,
            success_rate=round(verified / len(results), 4) if results else 0.0,
            truly_done=sum(r.truly_done is True for r in results),
            false_successes=sum(r.verified and r.truly_done is False for r in results),
            false_failures=sum(not r.verified and r.truly_done is True for r in results),
            truth_unknown=sum(r.truly_done is None for r in started),
            refused_before_start=len(results) - len(started),
            load_faults=sum(r.load_fault for r in results),
            failed_in=dict(sorted(Counter(r.failed_in for r in results if not r.verified and r.failed_in).items())),
            median_wall_s=round(statistics.median(walls), 2) if walls else None,
        )

    def outcome(self) -> dict:
        """Everything but the timing: what two campaigns over the same cases must agree on."""
        return self.model_dump(exclude={"median_wall_s"})


class CampaignTable(BaseModel):
    by_task: list[Row]
    by_action: list[Row]
    total: Row

    @classmethod
    def of(cls, results: Iterable[CaseResult]) -> CampaignTable:
        """Tasks in the order their runs come (the campaign's order), actions alphabetically."""
        results = list(results)
        tasks: dict[str, list[CaseResult]] = {}
        actions: dict[str, list[CaseResult]] = {}
        for r in results:
            tasks.setdefault(r.case.task, []).append(r)
            actions.setdefault(r.case.action, []).append(r)
        return cls(
            by_task=[Row.of(k, v) for k, v in tasks.items()],
            by_action=[Row.of(k, v) for k, v in sorted(actions.items())],
            total=Row.of("all", results),
        )

    def outcome(self) -> dict:
        return {
            "by_task": [r.outcome() for r in self.by_task],
            "by_action": [r.outcome() for r in self.by_action],
            "total": self.total.outcome(),
        }
