"""trajectories.npz reads back what was saved; tracking error is measured as the executor measures it (against the
set-points of the last lag); the plots draw from it, and a run that ended before planning draws only its
timeline."""

from __future__ import annotations

import numpy as np
from PIL import Image

from runtime.run import plots
from runtime.run.report import render_report
from runtime.run.summary import RunSummary, TransitionRecord
from runtime.run.trajectories import ExecutedPhase, PlannedPhase, RunTrajectories

DT = 0.004


def synthetic(delay_ticks: int = 2) -> RunTrajectories:
    t = np.arange(300) * DT
    q = np.stack([0.5 * np.sin(t * (j + 1)) for j in range(7)], axis=1)
    measured = np.vstack([np.repeat(q[:1], delay_ticks, axis=0), q[:-delay_ticks]])  # the arm trails by 2 ticks
    planned = PlannedPhase("approach", DT, q, True, 300, 900, 0.02, clearance=np.stack([t[::10], 0.1 + t[::10]], 1))
    executed = ExecutedPhase("approach", "completed", 0.0, t, t, q, measured)
    limits = np.full(7, 2.0)
    return RunTrajectories(tuple(f"joint{i}" for i in range(1, 8)), -limits, limits, limits, (planned,), (executed,))


def test_the_file_reads_back_what_was_saved(tmp_path):
    traj = synthetic()
    traj.save(tmp_path)
    back = RunTrajectories.load(tmp_path)
    assert back.joint_names == traj.joint_names and back.planned[0].name == "approach"
    assert np.array_equal(back.planned[0].positions, traj.planned[0].positions)
    assert np.array_equal(back.planned[0].clearance, traj.planned[0].clearance)
    assert np.array_equal(back.executed[0].q_meas, traj.executed[0].q_meas) and back.executed[0].status == "completed"
    assert RunTrajectories.load(tmp_path / "none") is None


def test_tracking_error_allows_the_measured_state_to_trail_by_the_lag():
    phase = synthetic(delay_ticks=2).executed[0]
    same_tick = phase.tracking_error_rad(0.0)
    within_lag = phase.tracking_error_rad(3 * DT)
    assert same_tick.max() > 1e-3  # against the same tick's set-point, a 2-tick lag looks like an error
    assert within_lag.max() < 1e-12  # against the last 3 ticks' set-points it is none


def test_plots_draw_the_run_and_the_report_shows_them(tmp_path):
    traj = synthetic()
    summary = RunSummary(run_id="r", status="DONE", reason="goal reached")
    for i, (a, b) in enumerate([("IDLE", "CAPTURING"), ("CAPTURING", "PLANNING"), ("PLANNING", "DONE")]):
        summary.transitions = [*summary.transitions, TransitionRecord(previous=a, state=b, reason="", stamp_s=i)]
    drawn = [
        plots.timeline_plot(summary, tmp_path / "timeline.png"),
        plots.joints_plot(traj, tmp_path / "joints.png"),
        plots.tracking_plot(traj, 0.05, 0.03, tmp_path / "tracking.png"),
        plots.clearance_plot(traj, 0.01, tmp_path / "clearance.png"),
    ]
    for path in drawn:
        pixels = np.asarray(Image.open(path).convert("RGB"))
        assert pixels.shape[1] > 500 and len(np.unique(pixels.reshape(-1, 3), axis=0)) > 20  # a drawing, not blank
    empty = RunTrajectories(traj.joint_names, traj.lower, traj.upper, traj.velocity_limit, (), ())
    assert plots.joints_plot(empty, tmp_path / "x.png") is None
    assert plots.tracking_plot(empty, 0.05, 0.03, tmp_path / "y.png") is None
    page = render_report(summary, [("joints.png", "Joints against their limits")])
    assert page.index('id="status"') < page.index('src="joints.png"') < page.index('id="raw"')
    assert "<details" in page and "open" not in page.split('id="raw"')[1][:20]
