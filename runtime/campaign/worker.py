"""One case, run where a worker is (a process on this machine or a Ray worker anywhere): a whole `goalvla run`
on its own simulator, with its own Zenoh robot id and loopback port so that runs never hear each other, written
into a fresh run folder and handed back packed (tar) so that every backend gathers results the same way.

The pipeline's backends are built once per worker process and kept for its later cases, like a long-running
runtime. A run that this machine's load stopped (a starved simulated robot or e-stop heartbeat: results.LOAD_FAULTS)
is run once more, the first attempt's record kept inside the second's folder. Stepped, the simulated physics
advances only as the executor's clock waits (drivers.sim.SteppedClock): a loaded machine cannot starve the
simulated robot, and the wall times then say nothing of real time.
"""

from __future__ import annotations

import io
import logging
import os
import socket
import tarfile
import tempfile
import time
from pathlib import Path

from runtime.campaign.cases import Case
from runtime.campaign.results import RESULT_FILE, CaseResult

log = logging.getLogger(__name__)
_stages = None  # this worker process's ((contact, stepped), stages): backends loaded once
EARLIER_ATTEMPT = "load_fault_attempt"  # the folder, inside a case's, of an attempt this machine's load stopped
STEPPED_DEADMAN_S = 1.0  # the in-process e-stop heartbeat still beats by the wall clock while the physics is stepped


def free_port() -> int:
    """A free TCP port on this machine's loopback (the run's Zenoh endpoint)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def profile_overrides(case: Case, campaign: str, rerun_recording: bool, stepped: bool = False) -> dict:
    robot_id = f"eval-{campaign}-{case.id}".replace(".", "_")[:120]
    overrides = {
        "sim": {"scene": case.scene, "seed": case.sim_seed},
        "runtime": {
            "robot_id": robot_id,
            "zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"},
            "rerun_recording": rerun_recording,
        },
    }
    if stepped:
        overrides["sim"]["realtime"] = False
        overrides["runtime"]["deadman_timeout_s"] = STEPPED_DEADMAN_S
    return overrides


def _refusal(case: Case, profile) -> str | None:
    """Why the run would not start (as `goalvla run` refuses before any device opens), or None."""
    from drivers.sim.generate import check_scene
    from drivers.sim.scene import SceneError
    from pipeline.reasoning.factory import preflight
    from pipeline.reasoning.instruction import InstructionError, check_instruction

    problems = preflight(profile.pipeline)
    if profile.pipeline.vlm == "offline":
        try:
            check_instruction(case.instruction)
        except InstructionError as e:
            problems.append(str(e))
    try:
        check_scene(profile.sim)
    except SceneError as e:
        problems.append(str(e))
    return "; ".join(problems) or None


def stepped_clock(devices):
    """The executor's clock that steps the run's simulated world (drivers.sim.SteppedClock)."""
    from drivers.sim import SteppedClock

    return SteppedClock(devices.world)


def build_stages(contact: str, stepped: bool = False):
    """The run's stages: the pipeline's own, or with the simulator's ground-truth grasp standing in for contact
    planning (to measure the rest while contact is under work); stepped: the physics advanced by the executor's
    clock."""
    from runtime.run.stages import PipelineStages
    from runtime.sim_truth.listener import SimTruth

    clock = stepped_clock if stepped else None
    if contact == "oracle":
        from runtime.sim_truth.oracle import GroundTruthGraspStages

        return GroundTruthGraspStages(listeners=[SimTruth()], clock=clock)
    return PipelineStages(listeners=[SimTruth()], clock=clock)


def _attempt(case: Case, profile, run_dir: Path, contact: str, stepped: bool) -> CaseResult:
    """One whole run of the case into run_dir (new)."""
    global _stages
    from runtime.devices import open_devices
    from runtime.run.runner import Runtime

    if _stages is None or _stages[0] != (contact, stepped):
        _stages = ((contact, stepped), build_stages(contact, stepped))
    run, t0 = None, time.perf_counter()
    try:
        with open_devices(profile) as devices, Runtime(profile, devices, _stages[1], confirm="yes") as rt:
            run = rt.run(case.instruction, run_dir)
    except Exception:
        if run is None:
            raise
        # the run ended and its record is written; closing its devices failed (a stage that overran its budget
        # still holding the camera's GL context): the result stands, and the next case gets fresh backends
        log.exception("case %s: closing the devices after the run failed", case.id)
        _stages = None
    return CaseResult.of(case, run.summary, worker_name(), time.perf_counter() - t0)


def run_case(
    case: Case,
    config: Path,
    campaign: str,
    run_dir: Path,
    rerun_recording: bool = True,
    contact: str = "pipeline",
    stepped: bool = False,
) -> CaseResult:
    """Run the case into run_dir (new) and write its result.json there; once more when this machine's load
    stopped it."""
    from runtime.config import load_profile

    profile = load_profile(config, profile_overrides(case, campaign, rerun_recording, stepped))
    refusal = _refusal(case, profile)
    if refusal is not None:
        run_dir.mkdir(parents=True, exist_ok=True)
        result = CaseResult.refused(case, refusal, worker_name())
    else:
        load = os.getloadavg()[0]
        result = _attempt(case, profile, run_dir, contact, stepped)
        if result.load_fault:  # the machine's fault, not the run's: once more, the first record kept
            log.warning("case %s: stopped by this machine's load (%s): run again", case.id, result.reason[:120])
            earlier = run_dir.rename(run_dir.with_name(f".{run_dir.name}-{EARLIER_ATTEMPT}"))
            result = _attempt(case, profile, run_dir, contact, stepped).model_copy(
                update={"ran_again_after": result.reason}
            )
            earlier.rename(run_dir / EARLIER_ATTEMPT)
        result.load_1min = round((load + os.getloadavg()[0]) / 2, 2)
    (run_dir / RESULT_FILE).write_text(result.model_dump_json(indent=2))
    return result


def execute_case(
    case_json: str,
    config: str,
    campaign: str,
    rerun_recording: bool = True,
    contact: str = "pipeline",
    stepped: bool = False,
) -> tuple[str, bytes]:
    """The unit of work of every backend: run the case in a temporary folder and return (case id, the folder as
    tar bytes). Plain arguments and results, so a process pool and Ray carry them alike."""
    case = Case.model_validate_json(case_json)
    with tempfile.TemporaryDirectory(prefix="goalvla-eval-") as tmp:
        run_dir = Path(tmp) / case.id
        run_case(case, Path(config), campaign, run_dir, rerun_recording, contact, stepped)
        buffer = io.BytesIO()
        with tarfile.open(fileobj=buffer, mode="w") as tar:
            tar.add(run_dir, arcname=case.id)
        return case.id, buffer.getvalue()


def unpack(case_id: str, packed: bytes, runs_dir: Path) -> Path:
    """Put a returned run folder at runs_dir/<case id>, whole or not at all (a partial one is never left there)."""
    target = runs_dir / case_id
    with tempfile.TemporaryDirectory(prefix=f".{case_id}-", dir=runs_dir) as tmp:
        with tarfile.open(fileobj=io.BytesIO(packed), mode="r") as tar:
            tar.extractall(tmp, filter="data")
        extracted = Path(tmp) / case_id
        if not (extracted / RESULT_FILE).is_file():
            raise ValueError(f"case {case_id}: the returned run folder holds no {RESULT_FILE}")
        if target.exists():  # an earlier attempt that never finished (no result.json): replaced
            import shutil

            shutil.rmtree(target)
        extracted.rename(target)
    return target
