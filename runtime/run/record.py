"""The run record: one folder per run with summary.json, the images and report.html, mirrored on the bus.

Everything a stage decided goes into its section of the RunSummary (runtime.run.summary), so a failed run can be
understood from its folder alone, and every image through here, so the console sees the images the folder keeps.
"""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from drivers.description import load_robot_spec
from motion.executor import ExecutorConfig
from motion.limits import MotionLimits
from runtime.messaging.bus import Bus
from runtime.run import plots
from runtime.run.clearance import clearance_along

# Rerun loads with the runtime, before any run: its import takes about a second and holds other threads for up to
# ~0.1 s at a time, which must not happen while a run streams or its deadman heartbeat is watched
from runtime.run.recording import write_recording
from runtime.run.report import render_report
from runtime.run.summary import RunSummary, TransitionRecord
from runtime.run.trajectories import RunTrajectories
from runtime.supervision.states import Transition

if TYPE_CHECKING:  # the context holds this record
    from runtime.run.context import RunContext

log = logging.getLogger(__name__)

PUBLISHED_JPEG_QUALITY = 85


def to_bgr(image: np.ndarray) -> np.ndarray:
    """RGB uint8 image or boolean mask -> BGR uint8 for OpenCV."""
    if image.dtype == bool:
        return np.repeat((image.astype(np.uint8) * 255)[..., None], 3, axis=2)
    if image.ndim == 2:
        return cv2.cvtColor(image.astype(np.uint8), cv2.COLOR_GRAY2BGR)
    return cv2.cvtColor(image.astype(np.uint8), cv2.COLOR_RGB2BGR)


def publish_image(bus: Bus, name: str, bgr: np.ndarray) -> None:
    """images/<name> as JPEG (the console's view; the run folder keeps lossless PNGs)."""
    ok, jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, PUBLISHED_JPEG_QUALITY])
    if ok:
        bus.publish(bus.keys.image(name), jpeg.tobytes())


def run_folder_problem(path: Path) -> str | None:
    """Why `path` cannot take a new run, or None. A run folder is new (or empty): an earlier run's record is never
    overwritten, and a file where the folder should be is not replaced."""
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            return f"{path} exists and is not a folder"
        if any(path.iterdir()):
            return f"{path} already holds files (an earlier run?): give a new folder"
        return None if os.access(path, os.W_OK) else f"{path} is not writable"
    ancestor = path.parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        return f"{ancestor} is not a folder, so {path} cannot be made"
    return None if os.access(ancestor, os.W_OK) else f"{ancestor} is not writable, so {path} cannot be made"


class RunRecord:
    def __init__(self, run_dir: Path, run_id: str, bus: Bus | None = None) -> None:
        problem = run_folder_problem(run_dir)
        if problem is not None:
            raise FileExistsError(f"run folder: {problem}")
        self.dir = run_dir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.run_id = run_id
        self.bus = bus
        self.summary = RunSummary(run_id=run_id)
        self.images: list[str] = []
        self._t0 = time.monotonic()

    def on_transition(self, t: Transition) -> None:
        if t.previous.value not in ("IDLE", "DONE", "FAILED", "ESTOPPED"):
            key = t.previous.value.lower()
            seconds = self.summary.stage_seconds
            seconds[key] = round(seconds.get(key, 0.0) + t.seconds_in_previous, 4)
        record = TransitionRecord(previous=t.previous.value, state=t.state.value, reason=t.reason, stamp_s=t.stamp_s)
        self.summary.transitions = [*self.summary.transitions, record]

    def image(self, name: str, image: np.ndarray) -> Path:
        """Write <name>.png (RGB image or bool mask) and publish it as JPEG on images/<name>."""
        bgr = to_bgr(image)
        path = self.dir / f"{name}.png"
        if not cv2.imwrite(str(path), bgr):
            raise OSError(f"could not write {path}")
        if name not in self.images:
            self.images.append(name)
        if self.bus is not None:
            publish_image(self.bus, name, bgr)
        return path

    def finish(self, status: str, reason: str, ctx: RunContext | None = None) -> Path:
        """Write summary.json, then (from the ended run's context, when given) trajectories.npz, the plots,
        run.rrd (runtime.rerun_recording) and report.html, and summary.json again with the seconds each took.
        Nothing is done while the arm moves: the run has ended. A plot or the recording that fails is logged and
        left out; the summary is already on disk."""
        summary = self.summary
        summary.status, summary.reason = status, reason
        summary.wall_s = round(time.monotonic() - self._t0, 3)
        summary.images = [f"{n}.png" for n in self.images]
        path = self.dir / "summary.json"
        self._write_summary(path)
        drawn: list[tuple[str, str]] = []
        seconds: dict[str, float] = {}
        if ctx is not None:
            t = time.perf_counter()
            trajectories = self._trajectories(ctx)
            seconds["trajectories"] = time.perf_counter() - t
            t = time.perf_counter()
            drawn = self._plots(ctx, trajectories)
            seconds["plots"] = time.perf_counter() - t
            if ctx.profile.runtime.rerun_recording:
                t = time.perf_counter()
                try:
                    write_recording(ctx, summary, trajectories, self.dir)
                except Exception:
                    log.exception("run.rrd could not be written")
                seconds["recording"] = time.perf_counter() - t
        t = time.perf_counter()
        (self.dir / "report.html").write_text(render_report(summary, drawn))
        seconds["report"] = time.perf_counter() - t
        summary.record_seconds = {k: round(v, 3) for k, v in seconds.items()}
        self._write_summary(path)
        return path

    def _write_summary(self, path: Path) -> None:
        """Whole or not at all: a reader never sees half a summary."""
        partial = path.with_name(f".{path.name}.partial")
        partial.write_text(self.summary.model_dump_json(indent=2))
        partial.replace(path)

    def _trajectories(self, ctx: RunContext) -> RunTrajectories | None:
        if ctx.manipulation is None:
            return None
        try:
            spec = load_robot_spec()
            traj = RunTrajectories.of(ctx, MotionLimits.from_config(ctx.profile.safety, spec), spec.joint_names)
            if ctx.clouds is not None:
                from safety.robot_model import RobotModel

                robot = RobotModel(spec)
                traj = traj.with_clearance(
                    [clearance_along(robot, p.positions, p.dt, ctx.clouds.scene) for p in traj.planned]
                )
            traj.save(self.dir)
            return traj
        except Exception:
            log.exception("trajectories.npz could not be written")
            return None

    def _plots(self, ctx: RunContext, traj: RunTrajectories | None) -> list[tuple[str, str]]:
        """(file, caption) of each plot drawn, in the report's order."""
        profile = ctx.profile
        wanted = [
            ("plot_timeline.png", "Stage timeline", lambda p: plots.timeline_plot(self.summary, p)),
        ]
        if traj is not None:
            wanted += [
                ("plot_joints.png", "Joints against their limits, per phase", lambda p: plots.joints_plot(traj, p)),
                (
                    "plot_tracking.png",
                    "Tracking error",
                    lambda p: plots.tracking_plot(
                        traj, profile.robot.tracking_error_max_rad, ExecutorConfig.tracking_lag_s, p
                    ),
                ),
                (
                    "plot_clearance.png",
                    "Clearance from the scene and the table along the planned path",
                    lambda p: plots.clearance_plot(traj, profile.safety.padding_m, p),
                ),
            ]
        drawn = []
        for name, caption, draw in wanted:
            try:
                if draw(self.dir / name) is not None:
                    drawn.append((name, caption))
            except Exception:
                log.exception("%s could not be drawn", name)
        return drawn
