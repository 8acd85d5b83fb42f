"""`goalvla eval`: a campaign of whole runs over tasks, seeds and trials, every run its own record under
OUT/runs/<case id>/, gathered into one folder whatever ran them, with the results table written as results.json,
results.md and results.html.

Resumable: a case whose folder holds result.json is done and not run again; a case that crashed (no result.json)
runs again. campaign.json pins what the folder holds, so a different campaign is not mixed into it.
"""

from __future__ import annotations

import json
import time
from concurrent.futures import FIRST_COMPLETED, Future, wait
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

from runtime.campaign.cases import Case, expand
from runtime.campaign.pools import Pool
from runtime.campaign.render import html_page, markdown, rich_tables
from runtime.campaign.results import CampaignTable, CaseResult
from runtime.campaign.worker import unpack

SPEC_FILE, RESULTS_FILE = "campaign.json", "results.json"


class CampaignError(RuntimeError):
    """The campaign cannot run as asked (a different campaign in the folder, an unknown task)."""


class CampaignSpec(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str
    config: str  # the profile, absolute
    tasks: tuple[str, ...]
    seeds: tuple[int, ...]
    trials: int
    rerun_recording: bool = True
    contact: Literal["pipeline", "oracle"] = "pipeline"  # oracle: the simulator's grasp (runtime.sim_truth.oracle)
    stepped: bool = False  # the physics advanced by the executor's clock: the machine's load cannot starve the robot

    def cases(self) -> list[Case]:
        try:
            return expand(self.tasks, self.seeds, self.trials)
        except ValueError as e:
            raise CampaignError(str(e)) from e


class CampaignOutcome(BaseModel):
    spec: CampaignSpec
    table: CampaignTable
    results: list[CaseResult]
    errors: dict[str, str]  # case id -> why it has no result (it runs again on resume)
    ran_now: int  # cases run by this invocation
    wall_s: float  # this invocation's wall time
    pool: str


def _pin(spec: CampaignSpec, out: Path) -> None:
    path = out / SPEC_FILE
    if path.is_file():
        earlier = CampaignSpec.model_validate_json(path.read_text())
        if earlier != spec:
            raise CampaignError(
                f"{out} holds another campaign ({path}: tasks {','.join(earlier.tasks)}, "
                f"{len(earlier.seeds)} seeds, {earlier.trials} trials, {earlier.config}); give a new --out"
            )
    else:
        out.mkdir(parents=True, exist_ok=True)
        path.write_text(spec.model_dump_json(indent=2))


def finished(cases: list[Case], runs: Path) -> dict[str, CaseResult]:
    """The cases that already have their result, by id."""
    out = {}
    for case in cases:
        result = CaseResult.read(runs / case.id)
        if result is not None:
            out[case.id] = result
    return out


def write_results(outcome: CampaignOutcome, out: Path) -> None:
    title = f"campaign {outcome.spec.name}"
    (out / RESULTS_FILE).write_text(outcome.model_dump_json(indent=2))
    (out / "results.md").write_text(markdown(outcome.table, title))
    spec = outcome.spec
    seeds = f"seeds {spec.seeds[0]}..{spec.seeds[-1]}" if spec.seeds else "no seeds"
    subtitle = (
        f"{len(outcome.results)} runs: tasks {', '.join(spec.tasks)}; {seeds}; {spec.trials} trial(s); profile "
        f"{Path(spec.config).name}; contact {spec.contact}{'; physics stepped' if spec.stepped else ''}; "
        f"on {outcome.pool}"
    )
    (out / "results.html").write_text(html_page(outcome.table, title, outcome.results, subtitle))


def run_campaign(spec: CampaignSpec, out: Path, pool: Pool, console: Console) -> CampaignOutcome:
    """Run every case not yet done on the pool, gather each run folder as it comes back, write the tables."""
    cases = spec.cases()
    _pin(spec, out)
    runs = out / "runs"
    runs.mkdir(exist_ok=True)
    done = finished(cases, runs)
    pending = [c for c in cases if c.id not in done]
    errors: dict[str, str] = {}
    t0 = time.monotonic()
    counts = f"{len(cases)} runs ({len(done)} already done, {len(pending)} to run)"
    console.print(f"campaign {spec.name}: {counts} on {pool.description}")
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    with Progress(*columns, TextColumn("eta"), TimeRemainingColumn(), console=console) as progress:
        bar = progress.add_task("runs", total=len(cases), completed=len(done))
        settings = (spec.config, spec.name, spec.rerun_recording, spec.contact, spec.stepped)
        futures: dict[Future, Case] = {pool.submit(c.model_dump_json(), *settings): c for c in pending}
        try:
            remaining = set(futures)
            while remaining:
                ready, remaining = wait(remaining, return_when=FIRST_COMPLETED)
                for future in ready:
                    case = futures[future]
                    try:
                        case_id, packed = future.result()
                        result = CaseResult.read(unpack(case_id, packed, runs))
                        done[case.id] = result
                        verdict = "verified" if result.verified else f"{result.status}: {result.reason[:90]}"
                        progress.console.print(f"  {case.id}: {verdict}")
                    except Exception as e:  # a crashed worker or run: no result, so it runs again on resume
                        errors[case.id] = f"{type(e).__name__}: {e}"
                        progress.console.print(f"  [red]{case.id}: no result ({errors[case.id][:120]})[/red]")
                    progress.advance(bar)
        except KeyboardInterrupt:
            pool.close(cancel=True)
            console.print("[yellow]interrupted: finished runs are kept; the same command resumes[/yellow]")
            raise
    results = [done[c.id] for c in cases if c.id in done]
    outcome = CampaignOutcome(
        spec=spec,
        table=CampaignTable.of(results),
        results=results,
        errors=errors,
        ran_now=len(pending) - len(errors),
        wall_s=round(time.monotonic() - t0, 2),
        pool=pool.description,
    )
    write_results(outcome, out)
    for table in rich_tables(outcome.table, f"campaign {spec.name}"):
        console.print(table)
    console.print(f"wrote {out / RESULTS_FILE}, results.md, results.html ({len(results)} runs under {runs})")
    return outcome


def read_outcome(out: Path) -> CampaignOutcome:
    return CampaignOutcome.model_validate(json.loads((out / RESULTS_FILE).read_text()))
