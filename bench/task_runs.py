"""Whole `goalvla run`s of the sweep, pick-up and take-off tasks on their scenes, each a fresh process through the
real command line, each run's verdict set against the simulator's truth of the task.

Tasks (scene, sentences; a seed picks the scene's layout and, for pick-up, which object):
  sweep     table_sweep  "sweep the screws into the dustpan"           done: >= 80 % of the screws over its floor
  pick up   pick_up      "pick up the red cup", ... one per object    done: touching only the fingers, >= 1 cm up
  take off  take_off     "take the red block off the stand",          done: off the stand (the rack), resting on
                         "take the orange plate out of the dish rack"       the table (the seeds alternate)
A run is a success when it exits 0 (verified); a false success is one the simulator's truth says is not done, a
missed success one that failed although the truth says done. Use seeds you did not tune on for the figures.

By default each run is `goalvla run` in its own process, physics on the wall clock as on hardware: on a loaded
machine a run may end in a stale-state or deadman stop that says nothing of the task. `--stepped` runs each case
in this process as `goalvla eval --stepped` does (runtime.campaign.worker: the physics stepped by the executor's
clock, a 1 s deadman), so the figures depend far less on the machine's load (the stage budgets and the e-stop
heartbeat still keep the wall clock).

    python bench/task_runs.py --seeds 300:310 --out tasks.json [--tasks sweep,pick_up] [--runs-dir DIR] [--stepped]
"""

from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

# bench/ holds runtime.py, which would shadow the runtime package: drop this folder from the import path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "configs" / "sim.yaml"
PICK_UP = (
    "pick up the red cup",
    "pick up the green cup",
    "pick up the blue block",
    "pick up the yellow block",
    "lift the purple bottle by 8 cm",
)
TASKS = {
    "sweep": ("table_sweep", ("sweep the screws into the dustpan",)),
    "pick_up": ("pick_up", PICK_UP),
    "take_off": ("take_off", ("take the red block off the stand", "take the orange plate out of the dish rack")),
}
TARGETS = {"sweep": 0.7, "pick_up": 0.95, "take_off": 0.9, "false_successes": 0}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run_stepped(task: str, scene: str, seed: int, instruction: str, record: Path) -> tuple[int, str]:
    """One run in this process as a stepped campaign runs it (runtime.campaign.worker: the physics stepped by the
    executor's clock); (exit code as the CLI's, output)."""
    from runtime.campaign.cases import Case
    from runtime.campaign.worker import run_case as run_campaign_case

    case = Case(task=task, scene=scene, instruction=instruction, seed=seed, trial=0, sim_seed=seed, action=task)
    result = run_campaign_case(case, CONFIG, "task_runs", record, stepped=True)
    return (0 if result.verified else 3 if result.status == "ESTOPPED" else 1), result.reason


def run_case(task: str, seed: int, runs_dir: Path, profile: Path, stepped: bool) -> dict:
    scene, sentences = TASKS[task]
    instruction = sentences[seed % len(sentences)]
    record = runs_dir / f"{task}-{seed}"
    t0 = time.perf_counter()
    if stepped:
        code, output = run_stepped(task, scene, seed, instruction, record)
    else:
        cmd = [sys.executable, "-m", "runtime.commands.cli", "run", "--config", str(profile), "--scene", scene]
        cmd += ["--seed", str(seed), "--instruction", instruction, "--yes", "--record", str(record)]
        proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=900)
        code, output = proc.returncode, (proc.stderr or proc.stdout)
    out = {"task": task, "seed": seed, "instruction": instruction, "exit_code": code}
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    summary_path = record / "summary.json"
    if not summary_path.exists():
        return out | {"outcome": "no record", "reason": output[-600:]}
    summary = json.loads(summary_path.read_text())
    failed_in = next(
        (
            t["previous"].lower()
            for t in summary["transitions"]
            if t["state"] != "DONE" and t["state"] in ("FAILED", "ESTOPPED")
        ),
        None,
    )
    truth = ((summary.get("sim_truth") or {}).get("task")) or {}
    verified = summary["status"] == "DONE"
    done = bool(truth.get("done"))
    out |= {
        "status": summary["status"],
        "reason": summary.get("reason", "")[:400],
        "failed_in": failed_in,
        "verified": verified,
        "done_truth": done,
        "truth": truth.get("detail"),
    }
    if verified:
        out["outcome"] = "verified" + ("" if done else " (FALSE SUCCESS)")
    else:
        out["outcome"] = f"failed in {failed_in}" + (" (done by truth)" if done else "")
    return out


def tally(rs: list[dict]) -> dict:
    """Runs, verified, done by the truth, false and missed successes of some runs."""
    return {
        "runs": len(rs),
        "verified": sum(bool(r.get("verified")) for r in rs),
        "done_truth": sum(bool(r.get("done_truth")) for r in rs),
        "false_successes": sum(bool(r.get("verified")) and not r.get("done_truth") for r in rs),
        "missed_successes": sum(not r.get("verified") and bool(r.get("done_truth")) for r in rs),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="300:310", help="A:B, the seeds A..B-1 (each task runs every seed)")
    parser.add_argument("--tasks", default=",".join(TASKS), help=f"comma-separated, of {', '.join(TASKS)}")
    parser.add_argument("--runs-dir", type=Path, default=None)
    parser.add_argument("--stepped", action="store_true", help="in this process, the physics stepped (load-free)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    a, b = (int(x) for x in args.seeds.split(":"))
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = set(tasks) - set(TASKS)
    if unknown:
        parser.error(f"unknown task(s) {', '.join(sorted(unknown))}; known: {', '.join(TASKS)}")
    console = Console()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        runs_dir = args.runs_dir or Path(tmp) / "runs"
        profile = Path(tmp) / "profile.yaml"  # own loopback port: other runs on this machine keep theirs
        profile.write_text(f"include: {CONFIG}\nruntime: {{zenoh: {{endpoint: tcp/127.0.0.1:{free_port()}}}}}\n")
        for task in tasks:
            for seed in range(a, b):
                r = run_case(task, seed, runs_dir, profile, args.stepped)
                console.print(
                    f"{task} {seed}: {r['instruction']!r} -> {r['outcome']} ({r['wall_s']} s) {r.get('truth')}"
                )
                results.append(r)
    table = Table(title=f"task runs, seeds {a}..{b - 1}" + (" (stepped)" if args.stepped else ""))
    for column in ("task", "runs", "verified", "done (truth)", "false successes", "missed successes", "ended in"):
        table.add_column(column)
    measured: dict = {}
    for task in tasks:
        rs = [r for r in results if r["task"] == task]
        ended = Counter(r.get("failed_in") or r["outcome"] for r in rs if not r.get("verified"))
        row = {
            **tally(rs),
            "per_sentence": {s: tally([r for r in rs if r["instruction"] == s]) for s in TASKS[task][1]},
            "ended_in": dict(ended),
            "median_wall_s": float(np.median([r["wall_s"] for r in rs])) if rs else None,
        }
        row["success_rate"] = round(row["verified"] / max(len(rs), 1), 3)
        measured[task] = row
        table.add_row(
            task,
            *(str(row[k]) for k in ("runs", "verified", "done_truth", "false_successes", "missed_successes")),
            ", ".join(f"{k} {v}" for k, v in ended.items()),
        )
    console.print(table)
    met = {t: measured[t]["success_rate"] >= TARGETS[t] for t in tasks}
    met["false_successes"] = sum(measured[t]["false_successes"] for t in tasks) <= TARGETS["false_successes"]
    console.print(met)
    report = {"targets": TARGETS, "met": met, "measured": measured, "stepped": args.stepped, "runs": results}
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
