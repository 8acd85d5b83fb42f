"""The report's plots, drawn with matplotlib (Agg, no display) into PNGs beside report.html: joint positions and
velocities against their limits per phase, tracking error, clearance along the path and the stage timeline.

Each function takes the run's data and a path and returns the path it wrote, or None when the run has nothing to
draw (it ended before planning, or before execution).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from runtime.run.summary import RunSummary
from runtime.run.trajectories import RunTrajectories

DPI = 90
PHASE_COLOURS = ("#dbe9f6", "#fde2c8", "#dcefd6", "#f3d9ec", "#ece7d2", "#d9eeee")
STATE_COLOURS = {
    "CAPTURING": "#8da0cb",
    "REASONING": "#66c2a5",
    "GROUNDING": "#fc8d62",
    "PLANNING": "#e78ac3",
    "AWAITING_CONFIRM": "#bbbbbb",
    "EXECUTING": "#a6d854",
    "VERIFYING": "#ffd92f",
}
JOINT_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2")
END_COLOURS = {"DONE": "#1a7f37", "FAILED": "#b35900", "ESTOPPED": "#cc0000"}


def _pyplot():
    """pyplot on the Agg backend (never a window or a display), imported when a report is drawn, not at start-up."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _phase_starts(traj: RunTrajectories) -> list[float]:
    """Where each planned phase starts on the motion's time axis: when it was streamed, or end to end."""
    executed = {e.name: e.start_s for e in traj.executed}
    starts, t = [], 0.0
    for p in traj.planned:
        t = executed.get(p.name, t)
        starts.append(t)
        t += len(p.positions) * p.dt
    return starts


def _shade_phases(ax, traj: RunTrajectories, starts: list[float], label: bool) -> None:
    for i, (p, t0) in enumerate(zip(traj.planned, starts, strict=True)):
        ax.axvspan(t0, t0 + len(p.positions) * p.dt, color=PHASE_COLOURS[i % len(PHASE_COLOURS)], lw=0, zorder=0)
        if label:
            ax.text(t0, 1.02, p.name, transform=ax.get_xaxis_transform(), fontsize=8, va="bottom")


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    _pyplot().close(fig)
    return path


def joints_plot(traj: RunTrajectories, path: Path) -> Path | None:
    """Every joint's position as a fraction of its range (limits at 0 and 1) and its velocity as a fraction of
    its limit (limits at -1 and 1), planned (lines) and measured (dashed), over the phases."""
    if not traj.planned:
        return None
    plt = _pyplot()
    starts = _phase_starts(traj)
    span = traj.upper - traj.lower
    fig, (ax_q, ax_v) = plt.subplots(2, 1, figsize=(11, 5.2), sharex=True)
    fig.subplots_adjust(left=0.07, right=0.86, top=0.93, bottom=0.09, hspace=0.18)
    for ax in (ax_q, ax_v):
        _shade_phases(ax, traj, starts, label=ax is ax_q)
        ax.tick_params(labelsize=7)
    for j, name in enumerate(traj.joint_names):
        colour = JOINT_COLOURS[j % len(JOINT_COLOURS)]
        for k, (p, t0) in enumerate(zip(traj.planned, starts, strict=True)):
            step = max(1, len(p.positions) // 400)
            t = t0 + p.times[::step]
            label = name if k == 0 else None
            ax_q.plot(t, (p.positions[::step, j] - traj.lower[j]) / span[j], color=colour, lw=1.1, label=label)
            ax_v.plot(t, p.velocities[::step, j] / traj.velocity_limit[j], color=colour, lw=1.1)
        for e in traj.executed:
            if len(e.times_s):
                step = max(1, len(e.times_s) // 400)
                q = (e.q_meas[::step, j] - traj.lower[j]) / span[j]
                ax_q.plot(e.start_s + e.times_s[::step], q, color=colour, lw=0.8, ls="--")
    for ax, limits in ((ax_q, (0.0, 1.0)), (ax_v, (-1.0, 1.0))):
        for limit in limits:
            ax.axhline(limit, color="#cc0000", lw=1.0, ls=":")
    ax_q.set_ylim(-0.05, 1.05)
    ax_v.set_ylim(-1.1, 1.1)
    ax_q.set_ylabel("position / range\n(0 and 1: limits)", fontsize=8)
    ax_v.set_ylabel("velocity / limit", fontsize=8)
    ax_q.set_title("planned (solid), measured (dashed), limits (red dotted)", fontsize=9, pad=16)
    ax_v.set_xlabel("time from the start of the motion [s]", fontsize=8)
    ax_q.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return _save(fig, path)


def tracking_plot(traj: RunTrajectories, bound_rad: float, lag_s: float, path: Path) -> Path | None:
    """The largest joint's |measured - commanded| per tick, per phase, against the executor's bound."""
    if not traj.executed:
        return None
    fig, ax = _pyplot().subplots(figsize=(11, 2.4))
    fig.subplots_adjust(left=0.07, right=0.86, top=0.86, bottom=0.2)
    _shade_phases(ax, traj, _phase_starts(traj), label=True)
    for e in traj.executed:
        if len(e.times_s):
            step = max(1, len(e.times_s) // 600)
            error = np.degrees(e.tracking_error_rad(lag_s))[::step]
            ax.plot(e.start_s + e.times_s[::step], error, lw=1.0, color="#1f4e9c")
    ax.axhline(np.degrees(bound_rad), color="#cc0000", lw=1, ls="--", label=f"bound {np.degrees(bound_rad):.1f} deg")
    ax.set_ylabel("tracking error [deg]", fontsize=8)
    ax.set_xlabel("time from the start of the motion [s]", fontsize=8)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.tick_params(labelsize=7)
    return _save(fig, path)


def clearance_plot(traj: RunTrajectories, padding_m: float, path: Path) -> Path | None:
    """The robot's distance to the scene and the table along each planned phase."""
    phases = [p for p in traj.planned if len(p.clearance)]
    if not phases:
        return None
    starts = dict(zip([p.name for p in traj.planned], _phase_starts(traj), strict=True))
    fig, ax = _pyplot().subplots(figsize=(11, 2.4))
    fig.subplots_adjust(left=0.07, right=0.86, top=0.86, bottom=0.2)
    _shade_phases(ax, traj, _phase_starts(traj), label=True)
    for p in phases:
        ax.plot(starts[p.name] + p.clearance[:, 0], 1000 * p.clearance[:, 1], color="#1f4e9c", lw=1.2)
    ax.axhline(1000 * padding_m, color="#b35900", lw=1, ls="--", label=f"padding {1000 * padding_m:.0f} mm")
    ax.axhline(0, color="k", lw=0.8)
    ax.set_ylabel("clearance [mm]", fontsize=8)
    ax.set_xlabel("time from the start of the motion [s]", fontsize=8)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.tick_params(labelsize=7)
    return _save(fig, path)


def timeline_plot(summary: RunSummary, path: Path) -> Path | None:
    """One bar per state the run went through, in order, with its seconds; the end state marked."""
    spans = []
    for before, after in zip(summary.transitions, summary.transitions[1:], strict=False):
        if before.state in STATE_COLOURS:
            spans.append((before.state, before.stamp_s, after.stamp_s - before.stamp_s))
    if not spans:
        return None
    t0 = spans[0][1]
    fig, ax = _pyplot().subplots(figsize=(11, 1.3))
    fig.subplots_adjust(left=0.02, right=0.86, top=0.9, bottom=0.33)
    for state, start, seconds in spans:
        ax.barh(0, seconds, left=start - t0, color=STATE_COLOURS[state], edgecolor="white")
        if seconds > 0.04 * (spans[-1][1] + spans[-1][2] - t0):
            ax.text(
                start - t0 + seconds / 2, 0, f"{state.lower()}\n{seconds:.1f} s", ha="center", va="center", fontsize=7
            )
    end = summary.transitions[-1]
    ax.axvline(end.stamp_s - t0, color=END_COLOURS.get(end.state, "#555"), lw=3)
    ax.text(end.stamp_s - t0, 0.45, f" {end.state}", color=END_COLOURS.get(end.state, "#555"), fontsize=8)
    ax.set_yticks([])
    ax.set_xlabel("seconds from the run's start", fontsize=8)
    ax.tick_params(labelsize=7)
    return _save(fig, path)
