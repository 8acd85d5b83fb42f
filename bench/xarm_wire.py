"""The real xArm path on the wire: the executor streaming through xarm-python-sdk to the controller emulator over
loopback TCP, against the sim arm (in-process, no wire) as the baseline, in the same run.

1. Streaming at 100 and 250 Hz, sim arm and SDK + emulator: tick period jitter p50/p99/max, late ticks, CPU share
   of the streaming thread (its CPU time over its wall time), and the command-to-report latency: from the servo
   call to the arrival at the driver of the first 'real' report the controller sent after executing that set-point
   (the SDK path: one TCP round trip, up to one report period, the report's trip). The sim arm's state is read
   straight from the world, so its figure is the servo call alone. Targets: jitter p99 <= 1 ms at 250 Hz through
   the SDK (the ratio to the sim arm is in the JSON).
2. Protocol faults mid-trajectory (controller error, report dropped or silent, malformed and truncated reply,
   dropped command link): how long after the fault the executor detected it, and control ticks from detection to
   the controller receiving the stop.
   Target <= 2 ticks; with the command link dropped no stop can arrive, so the figure is the set-points executed
   after detection (must be 0).
3. Whole runs: `goalvla run --yes` as a subprocess with configs/sim.yaml and configs/emulated.yaml, the same scene
   and seeds, interleaved. Target: the emulated median within 1.5x the sim median.

Timings depend on the machine's load (the 2-core CI-class machine is shared); binding port 502 needs root.

    python bench/xarm_wire.py [--quick] --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from drivers.config import RobotConfig  # noqa: E402
from drivers.sim import SimArm, SimWorld  # noqa: E402
from drivers.xarm7 import XArm7  # noqa: E402
from drivers.xarm7.emulator import XArmEmulator  # noqa: E402
from motion.approval import approve  # noqa: E402
from motion.executor import Executor, ExecutorConfig  # noqa: E402
from motion.limits import MotionLimits  # noqa: E402
from motion.timing import TrajectoryTimer  # noqa: E402
from runtime.config import load_profile  # noqa: E402
from safety.collision import CollisionWorld  # noqa: E402
from safety.robot_model import RobotModel  # noqa: E402

SIM = REPO / "configs" / "sim.yaml"
EMULATED = REPO / "configs" / "emulated.yaml"
TARGETS = {"jitter_p99_ms_250hz_sdk": 1.0, "fault_stop_ticks_max": 2.0, "run_wall_ratio_emulated_to_sim": 1.5}
SWING = np.array([0.8, 0.3, 0.0, 0.3, 0.0, -0.3, 0.8])
FAULT_AT = 40
INSTRUCTION = "put the red block on the white plate"
REPORT_ANGLES = slice(7, 35)  # 7 float32 joint angles after size, state|mode, cmdnum (wire.real_report)


class TimedExecutor(Executor):
    """Records the streaming thread's CPU and wall time, and when a fault was detected (the stop call)."""

    def _run(self, traj) -> None:
        cpu0, wall0 = time.thread_time(), time.perf_counter()
        try:
            super()._run(traj)
        finally:
            self.cpu_s, self.wall_s = time.thread_time() - cpu0, time.perf_counter() - wall0

    def _stop_arm(self) -> None:
        self.detected_s = time.monotonic()
        super()._stop_arm()


def _key(q_rad) -> tuple:
    """A report's joints as the SDK keeps them (float32 on the wire, rounded to 6 decimals): pairs a report the
    driver received with the one the emulator sent."""
    return tuple(round(float(v), 6) for v in q_rad)


def _timed(cls):
    class Timed(cls):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.calls: list[tuple[float, float]] = []  # (start, end) of each servo call, time.monotonic()
            self.arrivals: list[tuple[float, tuple]] = []  # SDK only: (arrival, float32 joints) of each report

        def servo(self, q) -> None:
            t0 = time.monotonic()
            super().servo(q)
            self.calls.append((t0, time.monotonic()))

        def _on_report(self, data: dict) -> None:
            self.arrivals.append((time.monotonic(), _key(np.radians(data["joints"][:7]))))
            super()._on_report(data)

    return Timed


TimedSimArm, TimedXArm7 = _timed(SimArm), _timed(XArm7)


def _swing(arm, profile, robot: RobotModel, rate_hz: float, seconds: float):
    limits = MotionLimits.from_config(profile.safety, robot.spec, speed_scale=0.5)
    timer = TrajectoryTimer(limits, 1 / rate_hz, robot.joint_names, robot.tcp_positions, 1.0)
    q0 = arm.read_state().q
    legs = max(2, int(seconds / 1.2))
    waypoints = np.array([q0 + SWING * (k % 2) for k in range(legs + 1)])
    return approve(timer.time([waypoints]), CollisionWorld(robot.copy(), profile.safety), q_current=q0), limits


def _percentiles(values: list[float], prefix: str) -> dict:
    if not values:
        return {f"{prefix}_p50_ms": None, f"{prefix}_p99_ms": None, f"{prefix}_max_ms": None}
    v = 1000.0 * np.asarray(values)
    return {
        f"{prefix}_p50_ms": float(np.percentile(v, 50)),
        f"{prefix}_p99_ms": float(np.percentile(v, 99)),
        f"{prefix}_max_ms": float(v.max()),
    }


def _command_to_report(arm, emulator: XArmEmulator) -> list[float]:
    """Per set-point: the first report sent after the controller executed it, and when the driver received it."""
    arrivals: dict[tuple, list[float]] = {}
    for t, q in arm.arrivals:
        arrivals.setdefault(q, []).append(t)
    sent = [(t, _key(np.frombuffer(frame[REPORT_ANGLES], dtype="<f4"))) for t, frame in emulator.server.sent_reports]
    stamps = np.array([t for t, _ in sent])
    executed = [s.stamp_s for s in emulator.journal.accepted()][-len(arm.calls) :]
    out = []
    for (t_call, _), t_exec in zip(arm.calls, executed, strict=True):
        for t_sent, q in sent[int(np.searchsorted(stamps, t_exec)) :]:
            received = [t for t in arrivals.get(q, ()) if t >= t_sent]
            if received:  # else a report the SDK dropped (its queue keeps the newest): take the next one
                out.append(received[0] - t_call)
                break
    return out


def stream(backend: str, rate_hz: float, seconds: float, robot: RobotModel) -> dict:
    profile = load_profile(SIM, {"sim": {"realtime": True}, "robot": {"control_rate_hz": rate_hz}})
    world = SimWorld(profile.sim, profile.camera)
    emulator = None
    try:
        if backend == "sim":
            arm = TimedSimArm(world, rate_hz)
        else:
            emulator = XArmEmulator(world, None, rate_hz).start()
            arm = TimedXArm7(RobotConfig(kind="xarm7", ip=emulator.address, control_rate_hz=rate_hz), profile.safety)
        with arm:
            approved, limits = _swing(arm, profile, robot, rate_hz, seconds)
            ex = TimedExecutor(
                arm, ExecutorConfig.from_configs(arm.config if emulator else profile.robot, profile.safety), limits
            )
            report = ex.execute(approved)
    finally:
        if emulator is not None:
            emulator.stop()
        world.stop()
    latency = _command_to_report(arm, emulator) if emulator else [end - start for start, end in arm.calls]
    return {
        "status": report.status,
        "reason": report.reason,
        "ticks": report.ticks,
        "late_ticks": report.late_ticks,
        "jitter_p50_ms": 1000 * report.jitter.p50_s,
        "jitter_p99_ms": 1000 * report.jitter.p99_s,
        "jitter_max_ms": 1000 * report.jitter.max_s,
        "realtime_priority": report.realtime_priority,
        "cpu_share": ex.cpu_s / ex.wall_s,
        **_percentiles(latency, "command_to_report"),
    }


FAULTS = {
    "controller error 31": lambda e: e.error_after(FAULT_AT, 31),
    "report link dropped": lambda e: e.faults.after_setpoints(FAULT_AT, e.drop_report_link, "armed"),
    "report silent": lambda e: e.faults.after_setpoints(FAULT_AT, e.faults.silence_report, "armed"),
    "malformed reply": lambda e: e.faults.after_setpoints(FAULT_AT, e.faults.corrupt_next, "armed"),
    "truncated reply": lambda e: e.faults.after_setpoints(FAULT_AT, lambda: e.faults.corrupt_next("truncate"), "armed"),
    "command link dropped": lambda e: e.faults.after_setpoints(FAULT_AT, e.drop_command_link, "armed"),
}


def fault(name: str, robot: RobotModel, rate_hz: float = 100.0) -> dict:
    profile = load_profile(SIM, {"sim": {"realtime": True}})
    world = SimWorld(profile.sim, profile.camera)
    try:
        with XArmEmulator(world, None, rate_hz) as emulator:
            arm = XArm7(RobotConfig(kind="xarm7", ip=emulator.address, control_rate_hz=rate_hz), profile.safety)
            with arm:
                approved, limits = _swing(arm, profile, robot, rate_hz, 3.0)
                FAULTS[name](emulator)
                ex = TimedExecutor(arm, ExecutorConfig.from_configs(arm.config, profile.safety), limits)
                report = ex.execute(approved)
            detected = getattr(ex, "detected_s", None)
            onset = min(emulator.faults.fired.values())  # the n-th set-point, when the fault was switched on
            stops = [t for t in emulator.journal.stops if detected is not None and t >= detected]
            after = sum(1 for s in emulator.journal.accepted() if detected is not None and s.stamp_s > detected)
    finally:
        world.stop()
    stop_ticks = (stops[0] - detected) * rate_hz if stops else None
    return {
        "status": report.status,
        "reason": report.reason,
        "detection_ms_after_fault": None if detected is None else 1000 * (detected - onset),
        "stop_ticks_after_detection": stop_ticks,
        "setpoints_after_detection": after,
        "stop_reached_controller": bool(stops),
    }


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _free_loopback() -> str:
    from drivers.xarm7.emulator.server import bind_controller_ports

    address, *listeners = bind_controller_ports(None)
    for s in listeners:
        s.close()
    return address


def whole_runs(seeds: list[int], out_dir: Path) -> dict:
    walls: dict[str, list[float]] = {"sim": [], "emulated": []}
    statuses: dict[str, list[int]] = {"sim": [], "emulated": []}
    for seed in seeds:
        for name, base in (("sim", SIM), ("emulated", EMULATED)):
            profile = out_dir / f"{name}_{seed}.yaml"
            robot = f"robot: {{ip: {_free_loopback()}}}\n" if name == "emulated" else ""
            profile.write_text(
                f"include: {base}\n{robot}runtime: {{zenoh: {{endpoint: tcp/127.0.0.1:{_free_port()}}}}}\n"
            )
            args = ["run", "--config", str(profile), "--instruction", INSTRUCTION, "--yes", "--seed", str(seed)]
            t0 = time.perf_counter()
            done = subprocess.run(
                [sys.executable, "-m", "runtime.commands.cli", *args, "--record", str(out_dir / f"{name}_{seed}")],
                cwd=REPO,
                capture_output=True,
                text=True,
            )
            walls[name].append(time.perf_counter() - t0)
            statuses[name].append(done.returncode)
            Console(stderr=True).print(f"  run {name} seed {seed}: exit {done.returncode}, {walls[name][-1]:.1f} s")
    med = {k: statistics.median(v) for k, v in walls.items()}
    return {
        "run_seeds": seeds,
        "run_wall_s_sim": walls["sim"],
        "run_wall_s_emulated": walls["emulated"],
        "run_exit_codes_sim": statuses["sim"],
        "run_exit_codes_emulated": statuses["emulated"],
        "run_wall_ratio_emulated_to_sim": med["emulated"] / med["sim"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="short streams, one run each")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    console = Console(stderr=True)
    robot = RobotModel()
    seconds = 3.0 if args.quick else 10.0
    result: dict = {"quick": args.quick, "streaming": {}, "faults": {}}
    for rate in (100.0, 250.0):
        for backend in ("sim", "sdk"):
            console.print(f"streaming {backend} at {rate:g} Hz ...")
            result["streaming"][f"{backend}_{rate:g}hz"] = stream(backend, rate, seconds, robot)
    s = result["streaming"]
    for rate in ("100hz", "250hz"):
        sim_p99 = max(s[f"sim_{rate}"]["jitter_p99_ms"], 1e-6)
        result[f"jitter_p99_ratio_sdk_to_sim_{rate}"] = s[f"sdk_{rate}"]["jitter_p99_ms"] / sim_p99
    result["jitter_p99_ms_250hz_sdk"] = s["sdk_250hz"]["jitter_p99_ms"]
    for name in FAULTS:
        console.print(f"fault: {name} ...")
        result["faults"][name] = fault(name, robot)
    reachable = [f["stop_ticks_after_detection"] for f in result["faults"].values() if f["stop_reached_controller"]]
    result["fault_stop_ticks_max"] = max(reachable) if reachable else None
    result["fault_setpoints_after_detection_max"] = max(
        f["setpoints_after_detection"] for f in result["faults"].values()
    )
    with tempfile.TemporaryDirectory() as tmp:
        result |= whole_runs([0] if args.quick else [0, 1, 2], Path(tmp))
    met = {
        "jitter_p99_ms_250hz_sdk": result["jitter_p99_ms_250hz_sdk"] <= TARGETS["jitter_p99_ms_250hz_sdk"],
        "fault_stop_ticks_max": result["fault_stop_ticks_max"] is not None
        and result["fault_stop_ticks_max"] <= TARGETS["fault_stop_ticks_max"]
        and result["fault_setpoints_after_detection_max"] == 0
        and all(f["status"] == "fault" for f in result["faults"].values()),
        "run_wall_ratio_emulated_to_sim": result["run_wall_ratio_emulated_to_sim"]
        <= TARGETS["run_wall_ratio_emulated_to_sim"]
        and not any(result["run_exit_codes_sim"] + result["run_exit_codes_emulated"]),
    }
    result |= {"targets": TARGETS, "met": met}
    table = Table(title="xarm_wire: streaming (ms)")
    for column in ("backend", "jitter p50", "p99", "max", "late", "cmd->report p50", "p99", "max", "CPU share"):
        table.add_column(column)
    for key, r in s.items():
        table.add_row(
            key,
            *(f"{r[k]:.3f}" for k in ("jitter_p50_ms", "jitter_p99_ms", "jitter_max_ms")),
            str(r["late_ticks"]),
            *(
                f"{r[k]:.2f}"
                for k in ("command_to_report_p50_ms", "command_to_report_p99_ms", "command_to_report_max_ms")
            ),
            f"{r['cpu_share']:.2f}",
        )
    Console().print(table)
    faults = Table(title="xarm_wire: faults")
    columns = ("fault", "status", "detected after [ms]", "stop ticks after detection", "set-points after", "reason")
    for column in columns:
        faults.add_column(column, overflow="fold")
    for name, f in result["faults"].items():
        ticks = "-" if f["stop_ticks_after_detection"] is None else f"{f['stop_ticks_after_detection']:.2f}"
        late = "-" if f["detection_ms_after_fault"] is None else f"{f['detection_ms_after_fault']:.0f}"
        faults.add_row(name, f["status"], late, ticks, str(f["setpoints_after_detection"]), f["reason"][:60])
    Console().print(faults)
    summary = Table(title="xarm_wire: targets")
    for column in ("measure", "value", "target", "met"):
        summary.add_column(column)
    for key, target in TARGETS.items():
        value = result[key]
        summary.add_row(key, "-" if value is None else f"{value:.3f}", f"{target:g}", str(met[key]))
    Console().print(summary)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
