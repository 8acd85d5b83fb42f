"""Whole `goalvla run`s on generated scenes (drivers.sim.generate), each a fresh process through the real command
line, reported by the stage that ended them.

For each seed: the case's scene (`--scene gen:SEED`) and instruction run with `--yes --record DIR`. A sentence
outside the offline grammar must be refused before anything starts (exit 2). For the others: stage 1 (capture and
reasoning: segmentation, editing, reflection) passes when the run reaches GROUNDING with the initial target mask on
the case's target object (the simulator's own segmentation of the first capture, the lid body for "close");
later failures are counted by the state they ended in (grounding, planning = contact + motion + gate, executing,
verifying); "done (truth)" is the simulator's verdict: the target's centre within 3 cm of where the goal motion
puts it and, for a turn or a stand-up, its shape within 15 deg of the goal's turn (up to the turns its shape does
not show), for a push not tipped more than 15 deg, a lid within 15 deg of shut (the verification's tolerances). Per
action: verified, really done, false successes (verified, not done) and false failures (done, not verified).
A run that stopped because this machine starved the simulated robot, the e-stop heartbeat or the renderer (a stale
or stalled joint state report, a late heartbeat, a capture over its 5 s budget) is run once more
(--no-again-after-load-fault: not) and counted as such if it stops so again; the load average is recorded with
every run.
With --stepped the in-grammar runs go through the same Runtime and stages in this process with the physics
stepped by the executor's clock (a loaded machine cannot starve the simulated robot; wall times then say nothing
of real time). Use seeds you did not tune on for the figures.

    python bench/generated_runs.py --seeds 2000:2040 --out gen.json [--runs-dir runs/gen] [--quick] [--stepped]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from pathlib import Path

# bench/ holds runtime.py, which would shadow the runtime package: drop this folder from the import path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages

import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "configs" / "sim.yaml"
TARGETS = {"stage1_accepts_in_grammar": 0.95, "outside_grammar_refused": 1.0, "verified_and_done_fraction": 0.9}
TRUTH_TOL_M, TRUTH_TURN_DEG, LID_SHUT_DEG = 0.03, 15.0, 15.0  # the verification's own tolerances
TURN_JUDGED = ("rotate", "stand_up")  # a place may leave the object turned (dropped into a bowl)
TILT_JUDGED = ("push",)  # a push must not tip the object (a twist along the way is no matter)
LOAD_FAULTS = ("stale joint state", "the state report stalled", "no e-stop node heartbeat", "CAPTURING took too long")
STAGES = ("capturing", "reasoning", "grounding", "planning", "awaiting_confirm", "executing", "verifying")


def free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def true_target_mask(seed: int, target: str, lid: bool) -> np.ndarray:
    """The simulator's own segmentation of the scene as the first capture sees it (objects at rest)."""
    from drivers.sim import SimCamera, SimWorld
    from runtime.config import load_profile

    profile = load_profile(CONFIG, {"sim": {"scene": f"gen:{seed}", "realtime": False}})
    world = SimWorld(profile.sim, profile.camera)
    with SimCamera(world, seed=0) as camera:
        camera.read()
        return camera.body_mask(f"{target}_lid") if lid else camera.object_masks()[target]


def run_stepped(scene: str, instruction: str, record: Path) -> tuple[int, str]:
    """One run in this process, the physics stepped by the executor's clock (and a 1 s deadman: the in-process
    heartbeat still beats by the wall clock); (exit code as the CLI's, its reason)."""
    from drivers.sim import SteppedClock
    from runtime.config import load_profile
    from runtime.devices import open_devices
    from runtime.run.runner import Runtime
    from runtime.run.stages import PipelineStages
    from runtime.sim_truth.listener import SimTruth

    overrides = {
        "sim": {"scene": scene, "realtime": False},
        "runtime": {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "deadman_timeout_s": 1.0},
    }
    profile = load_profile(CONFIG, overrides)
    stages = PipelineStages(listeners=[SimTruth()], clock=lambda devices: SteppedClock(devices.world))
    with open_devices(profile) as devices, Runtime(profile, devices, stages, confirm="yes") as runtime:
        result = runtime.run(instruction, record)
    return (0 if result.ok else 3 if result.status.value == "ESTOPPED" else 1), result.reason


def run_case(seed: int, runs_dir: Path, profile: Path, attempt: int = 1, stepped: bool = False) -> dict:
    from drivers.sim.generate import generate_case

    case = generate_case(seed)
    task = case.task
    record = runs_dir / (f"gen-{seed}" if attempt == 1 else f"gen-{seed}-again")
    t0 = time.perf_counter()
    load = os.getloadavg()[0]
    if stepped and task.in_grammar:
        code, output = run_stepped(case.scene_name, task.instruction, record)
    else:
        cmd = [sys.executable, "-m", "runtime.commands.cli", "run", "--config", str(profile)]
        cmd += ["--scene", case.scene_name, "--instruction", task.instruction, "--yes", "--record", str(record)]
        proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
        code, output = proc.returncode, proc.stderr or proc.stdout
    out = {
        "load_1min": round((load + os.getloadavg()[0]) / 2, 2),
        "seed": seed,
        "instruction": task.instruction,
        "action": task.action + (f" {task.relation}" if task.relation else ""),
        "target": task.target,
        "exit_code": code,
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    if not task.in_grammar:
        out["outcome"] = "refused before start" if code == 2 else "NOT REFUSED"
        return out
    summary_path = record / "summary.json"
    if not summary_path.exists():
        out |= {"outcome": "no record", "reason": output[-600:]}
        return out
    summary = json.loads(summary_path.read_text())
    reached = [t["state"].lower() for t in summary.get("transitions", [])]
    failed_in = next((t["previous"].lower() for t in summary["transitions"] if t["state"] == "FAILED"), None)
    out |= {"status": summary["status"], "reason": summary.get("reason", ""), "failed_in": failed_in}
    stage1 = "grounding" in reached
    if stage1:
        mask = np.asarray(Image.open(record / "reasoning" / "mask_init.png").convert("L")) > 127
        truth = true_target_mask(seed, task.target, task.action == "close")
        iou = float((mask & truth).sum() / max((mask | truth).sum(), 1))
        out["target_iou"] = round(iou, 3)
        stage1 = iou >= 0.4
        out["wrong_target"] = not stage1
    out["stage1_ok"] = stage1
    truth = summary.get("sim_truth") or {}
    if task.action == "close":
        angle = (truth.get("hinge_deg") or {}).get(f"{task.target}_hinge")
        out["done_truth"] = angle is not None and angle <= LID_SHUT_DEG
    else:
        err, turn = truth.get("target_goal_error_m"), truth.get("target_turn_error_deg")
        tilt = truth.get("target_tilt_error_deg")
        placed = truth.get("target") == task.target and err is not None and err <= TRUTH_TOL_M
        turned = task.action not in TURN_JUDGED or (turn is not None and turn <= TRUTH_TURN_DEG)
        upright = task.action not in TILT_JUDGED or (tilt is not None and tilt <= TRUTH_TURN_DEG)
        out["done_truth"] = placed and turned and upright
    out["verified"] = summary["status"] == "DONE"
    out["load_fault"] = summary["status"] != "DONE" and any(f in summary.get("reason", "") for f in LOAD_FAULTS)
    return out


def group(action: str) -> str:
    """place on, place in, place beside (every side relation), or the action."""
    return action if action in ("place on", "place in") else "place beside" if action.startswith("place") else action


def outcome(r: dict) -> str:
    if "outcome" in r:
        return r["outcome"]
    if r.get("wrong_target"):
        return "stage 1: wrong target"
    if not r["stage1_ok"]:
        return f"failed in {r['failed_in']}"
    if r["verified"]:
        return "verified" + ("" if r["done_truth"] else " (FALSE SUCCESS)")
    if r.get("load_fault"):
        return "stopped: machine load"
    return f"failed in {r['failed_in']}" + (" (done by truth)" if r["done_truth"] else "")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="2000:2040", help="A:B, the seeds A..B-1")
    parser.add_argument("--quick", action="store_true", help="the first 4 seeds only")
    parser.add_argument("--runs-dir", type=Path, default=None)
    parser.add_argument(
        "--stepped",
        action="store_true",
        help="in-grammar cases in this process with the physics stepped by the executor's clock: figures that do "
        "not depend on the machine's load (wall times then do not measure real time)",
    )
    parser.add_argument(
        "--again-after-load-fault",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run a case once more when this machine's load stopped it (a starved simulated robot or heartbeat)",
    )
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    a, b = (int(x) for x in args.seeds.split(":"))
    seeds = list(range(a, min(b, a + 4) if args.quick else b))
    console = Console()
    with tempfile.TemporaryDirectory() as tmp:
        runs_dir = args.runs_dir or Path(tmp) / "runs"
        profile = Path(tmp) / "profile.yaml"  # own loopback port: other runs on this machine keep theirs
        profile.write_text(f"include: {CONFIG}\nruntime: {{zenoh: {{endpoint: tcp/127.0.0.1:{free_port()}}}}}\n")
        results = []
        for seed in seeds:
            r = run_case(seed, runs_dir, profile, stepped=args.stepped)
            if r.get("load_fault") and args.again_after_load_fault:  # the machine's fault, not the run's: once more
                console.print(f"{seed}: stopped by machine load ({r['reason'][:80]}), run again")
                again = run_case(seed, runs_dir, profile, attempt=2, stepped=args.stepped)
                r = again | {"ran_again_after": r["reason"]}
            r["outcome"] = outcome(r)
            console.print(f"{seed}: {r['instruction']!r} -> {r['outcome']} ({r['wall_s']} s)")
            results.append(r)
    in_grammar = [r for r in results if "stage1_ok" in r or r.get("outcome") == "no record"]
    outside = [r for r in results if r["outcome"] in ("refused before start", "NOT REFUSED")]
    by_action: dict[str, list[dict]] = defaultdict(list)
    for r in in_grammar:
        by_action[group(r["action"])].append(r)
    table = Table(title=f"generated runs, seeds {a}..{seeds[-1]}")
    for column in (
        "action",
        "cases",
        "verified",
        "really done",
        "false successes",
        "false failures",
        "machine load",
        "ended in",
    ):
        table.add_column(column)
    per_action = {}
    for action in sorted(by_action):
        rs = by_action[action]
        row = {
            "cases": len(rs),
            "verified": sum(bool(r.get("verified")) for r in rs),
            "done_truth": sum(bool(r.get("done_truth")) for r in rs),
            "false_successes": sum(bool(r.get("verified")) and not r.get("done_truth") for r in rs),
            "false_failures": sum(not r.get("verified") and bool(r.get("done_truth")) for r in rs),
            "load_faults": sum(bool(r.get("load_fault")) for r in rs),
            "ended_in": dict(Counter(r.get("failed_in") or "-" for r in rs if not r.get("verified"))),
        }
        per_action[action] = row
        table.add_row(action, *(str(v) for v in list(row.values())[:-1]), str(row["ended_in"] or ""))
    console.print(table)
    n = max(len(in_grammar), 1)
    stage1 = sum(bool(r.get("stage1_ok")) for r in in_grammar) / n
    refused = sum(r["outcome"] == "refused before start" for r in outside) / max(len(outside), 1)
    walls = [r["wall_s"] for r in in_grammar]
    measured = {
        "stage1_accepts_in_grammar": round(stage1, 3),
        "outside_grammar_refused": round(refused, 3),
        "in_grammar_runs": len(in_grammar),
        "verified": sum(bool(r.get("verified")) for r in in_grammar),
        "done_truth": sum(bool(r.get("done_truth")) for r in in_grammar),
        "verified_and_done_fraction": round(
            sum(bool(r.get("verified")) and bool(r.get("done_truth")) for r in in_grammar) / n, 3
        ),
        "false_successes": sum(bool(r.get("verified")) and not r.get("done_truth") for r in in_grammar),
        "false_failures": sum(not r.get("verified") and bool(r.get("done_truth")) for r in in_grammar),
        "false_failure_fraction": round(
            sum(not r.get("verified") and bool(r.get("done_truth")) for r in in_grammar) / n, 3
        ),
        "load_faults": sum(bool(r.get("load_fault")) for r in in_grammar),
        "ran_again_after_load_fault": sum("ran_again_after" in r for r in in_grammar),
        "failed_in": dict(Counter(r.get("failed_in") or "-" for r in in_grammar if not r.get("verified"))),
        "median_wall_s": float(np.median(walls)) if walls else None,
        "load_1min_median": float(np.median([r["load_1min"] for r in results])) if results else None,
        "stepped": args.stepped,
        "per_action": per_action,
    }
    met = {k: measured[k] >= v for k, v in TARGETS.items()}
    console.print(measured, met)
    args.out.write_text(json.dumps({"targets": TARGETS, "met": met, "measured": measured, "runs": results}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
