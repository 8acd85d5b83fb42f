"""Run one fuzz case in a process of its own, bounded in memory and time.

Each case is forked from a forkserver that has the project's modules preloaded (a fork costs milliseconds, a fresh
interpreter about a second), torch and open3d included: the commands import them lazily, and mapping their
libraries takes hundreds of MB of address space that says nothing about the input (under the limit below, a pair
valid enough to reach feature matching died in torch's import with std::bad_alloc). The child may grow its
address space by at most CASE_MEMORY_BYTES beyond what it was forked with (RLIMIT_AS), so a regression that tries
to allocate gigabytes fails that case with a MemoryError or a dead child instead of exhausting the machine; the
parent kills a child that runs past its timeout. `run_cli` invokes the `goalvla` command line in such a child and
returns what a user would see.
"""

from __future__ import annotations

import multiprocessing
import resource
import traceback
from dataclasses import dataclass

CASE_MEMORY_BYTES = 1 << 30  # the bound: under 1 GB per case
CASE_TIMEOUT_S = 60.0  # generous: the machine is shared; a hang is minutes, a case is milliseconds to seconds

_CTX = multiprocessing.get_context("forkserver")
_CTX.set_forkserver_preload(
    [
        "fuzz_harness",
        "runtime.commands.cli",
        "runtime.config",
        "safety.check_files",
        "safety.gate",
        "pipeline.grounding.pair_io",
        "torch",
        "open3d",
    ]
)


@dataclass(frozen=True)
class CliOutcome:
    exit_code: int
    output: str  # stdout and stderr as the user sees them
    traceback: str | None  # an exception that escaped the command (None: it ended by its own exit code)
    rss_growth_mb: float  # the child's peak resident memory minus what it was forked with


def _status_kb(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"/proc/self/status has no {field}")


def _child(conn, fn, args) -> None:
    try:
        limit = _status_kb("VmSize") * 1024 + CASE_MEMORY_BYTES
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
        start_rss_kb = _status_kb("VmRSS")
        result = fn(*args)
        growth_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - start_rss_kb) / 1024
        conn.send(("ok", (result, growth_mb)))
    except BaseException:  # everything goes back to the parent as text
        conn.send(("raised", traceback.format_exc()))
    finally:
        conn.close()


def bounded(fn, *args, timeout_s: float = CASE_TIMEOUT_S):
    """fn(*args) in a bounded child (fn and args must pickle: a module-level function). Returns (result,
    peak RSS growth in MB); AssertionError when the child raised, died or ran past timeout_s."""
    recv, send = _CTX.Pipe(duplex=False)
    proc = _CTX.Process(target=_child, args=(send, fn, args), daemon=True)
    proc.start()
    send.close()
    try:
        if not recv.poll(timeout_s):
            raise AssertionError(f"case ran past {timeout_s} s (a hang?)")
        kind, payload = recv.recv()
    except EOFError:
        proc.join(5)
        raise AssertionError(f"case process died (exit code {proc.exitcode}): out of memory or a crash") from None
    finally:
        if proc.is_alive():
            proc.kill()
        proc.join()
        recv.close()
    if kind == "raised":
        raise AssertionError(f"case raised in its process:\n{payload}")
    return payload


def _invoke_cli(args: list[str]) -> tuple[int, str, str | None]:
    from typer.testing import CliRunner

    from runtime.commands.cli import app

    result = CliRunner().invoke(app, args)
    escaped = result.exception is not None and not isinstance(result.exception, SystemExit)
    tb = "".join(traceback.format_exception(*result.exc_info)) if escaped else None
    return result.exit_code, result.output, tb


def run_cli(args: list[str], timeout_s: float = CASE_TIMEOUT_S) -> CliOutcome:
    (code, output, tb), growth = bounded(_invoke_cli, [str(a) for a in args], timeout_s=timeout_s)
    return CliOutcome(code, output, tb, growth)


def assert_refused(outcome: CliOutcome, *needles: str) -> None:
    """Exit 2 with `error:` and every needle (file name, key, problem) in what the user sees; no traceback."""
    assert outcome.traceback is None, outcome.traceback
    assert outcome.exit_code == 2, outcome.output
    assert "error:" in outcome.output or "Error" in outcome.output, outcome.output
    for needle in needles:
        assert needle in outcome.output, (needle, outcome.output)


def _profile_verdict(path: str) -> tuple[str, object]:
    """("refused", message) or ("loaded", the key paths of non-finite floats in the validated profile)."""
    import math

    from runtime.config import ConfigError, load_profile

    try:
        profile = load_profile(path)
    except ConfigError as e:
        return "refused", str(e)
    bad: list[str] = []

    def walk(node, key: str) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{key}.{k}")
        elif isinstance(node, (list, tuple)):
            for i, v in enumerate(node):
                walk(v, f"{key}.{i}")
        elif isinstance(node, float) and not math.isfinite(node):
            bad.append(key)

    walk(profile.model_dump(), "")
    return "loaded", bad


def load_profile_bounded(path) -> tuple[str, object]:
    return bounded(_profile_verdict, str(path))[0]


def _gate_summary(positions, dt: float, safety: dict, max_checks: int) -> dict:
    """What the gate says about a trajectory, reduced to what the fuzz tests check."""
    import json

    import numpy as np

    from safety.collision import CollisionWorld
    from safety.config import SafetyConfig
    from safety.gate import subsample_counts, validate
    from safety.robot_model import RobotModel
    from safety.trajectory import JointTrajectory

    robot = RobotModel()
    config = SafetyConfig(**safety)
    q = np.asarray(positions, dtype=np.float64)
    report = validate(JointTrajectory(robot.joint_names, dt, q), CollisionWorld(robot, config), max_checks=max_checks)
    listed: dict[str, int] = {}
    for v in report.violations:
        listed[v.kind] = listed.get(v.kind, 0) + 1
    try:
        json.dumps(report.to_dict(), allow_nan=False)
        json_ok = True
    except ValueError:
        json_ok = False
    needed = int(subsample_counts(q, config.collision_resolution_rad, robot.upper - robot.lower).sum()) + 1
    return {
        "ok": report.ok,
        "listed": listed,
        "omitted": report.omitted,
        "checked": report.configurations_checked,
        "needed": needed,
        "json_ok": json_ok,
        "seconds": report.seconds,
        "lower": robot.lower.tolist(),
        "upper": robot.upper.tolist(),
    }


def gate_bounded(positions, dt: float, safety: dict | None = None, max_checks: int = 1_000_000) -> dict:
    summary, growth = bounded(_gate_summary, positions, dt, safety or {}, max_checks)
    return {**summary, "rss_growth_mb": growth}
