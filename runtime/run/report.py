"""report.html: the run as a page a person reads, self-contained beside the run folder's images.

Top to bottom: the verdict with the reason and the pictures; the plots (stage timeline, joints against their
limits, tracking error, clearance); readable tables for the reasoning and grounding, the contact, the plan, the
execution, the verification and the simulator's truth; the raw summary.json folded away one click below.
"""

from __future__ import annotations

import html
import json
from collections.abc import Iterable, Sequence

import numpy as np

from runtime.run.summary import RunSummary

STATUS_COLOURS = {"DONE": "#1a7f37", "FAILED": "#b35900", "ESTOPPED": "#c00", "RUNNING": "#555"}
VERDICT_WORDS = {"DONE": "verified success", "FAILED": "failed", "ESTOPPED": "e-stopped", "RUNNING": "running"}
STYLE = """
body{font-family:system-ui,sans-serif;margin:1.2em auto;max-width:1180px;color:#222;padding:0 1em}
h1{font-size:1.3em;margin:0 0 .2em} h2{font-size:1.1em;margin:1.4em 0 .4em;border-bottom:1px solid #ddd}
.verdict{display:flex;gap:1em;align-items:baseline;flex-wrap:wrap}
.status{font-size:1.7em;font-weight:bold} .reason{font-size:1.05em;white-space:pre-wrap}
.meta{color:#555;font-size:.9em} .pictures{display:flex;flex-wrap:wrap;gap:6px}
figure{margin:0} figure img{width:186px;border:1px solid #ccc} figcaption{font-size:12px;color:#555}
.plot{max-width:100%;display:block;margin:.3em 0} table{border-collapse:collapse;margin:.4em 0 1em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:left;vertical-align:top;font-size:13px}
th{background:#f4f4f4} .tables{display:grid;grid-template-columns:repeat(auto-fit,minmax(340px,1fr));gap:0 1.5em}
.ok{color:#1a7f37} .bad{color:#b35900} details{margin:1.5em 0} pre{font-size:12px;background:#f7f7f7;padding:1em}
"""


def _e(value: object) -> str:
    return html.escape(str(value))


def _fmt(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list | tuple):
        return ", ".join(_fmt(v) for v in value)
    if isinstance(value, dict):
        return "; ".join(f"{k}: {_fmt(v)}" for k, v in value.items()) or "-"
    return str(value)


def _kv_table(title: str, rows: Iterable[tuple[str, object]], table_id: str) -> str:
    body = "".join(f"<tr><th>{_e(k)}</th><td>{_e(_fmt(v))}</td></tr>" for k, v in rows)
    return f'<div><h2>{_e(title)}</h2><table id="{table_id}">{body}</table></div>'


def _grid_table(title: str, header: Sequence[str], rows: Iterable[Sequence[object]], table_id: str) -> str:
    head = "".join(f"<th>{_e(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{_e(_fmt(v))}</td>" for v in row) + "</tr>" for row in rows)
    return f'<div><h2>{_e(title)}</h2><table id="{table_id}"><tr>{head}</tr>{body}</table></div>'


def _mm(metres: float | None) -> str:
    return "-" if metres is None else f"{1000 * metres:.1f} mm"


def _deg_of(R: list[list[float]]) -> float:
    c = (np.trace(np.asarray(R)) - 1) / 2
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def _tables(s: RunSummary) -> list[str]:
    out = []
    if s.reasoning is not None:
        r = s.reasoning
        out.append(
            _kv_table(
                "Goal (reasoning)",
                [
                    ("target", r.target),
                    ("editing prompt", r.prompt),
                    ("validated", r.validated),
                    ("iterations", r.iterations),
                    ("seconds", r.seconds),
                ],
                "reasoning",
            )
        )
    if s.object_motion is not None:
        m = s.object_motion
        out.append(
            _kv_table(
                "Object motion (grounding)",
                [
                    ("grounded", m.ok),
                    ("reason", m.reason or "-"),
                    (
                        "translation (base)",
                        "-"
                        if m.translation_base_m is None
                        else ", ".join(f"{1000 * v:.0f}" for v in m.translation_base_m) + " mm",
                    ),
                    ("rotation", f"{_deg_of(m.R):.1f} deg"),
                    ("scale", m.scale),
                    ("inliers / matches", f"{m.inliers} / {m.matches}"),
                    ("confidence", m.confidence),
                    ("residual", _mm(m.residual_m)),
                ],
                "grounding",
            )
        )
    if s.contact is not None:
        c = s.contact
        out.append(
            _kv_table(
                "Contact",
                [
                    ("mode", c.mode),
                    *([("carried instead of pushed", c.carried_because)] if c.carried_because else []),
                    ("candidates", c.candidates),
                    ("ranked plans", c.plans),
                    ("ruled out", c.rejected),
                    ("turn from grounded [deg]", c.turn_from_grounded_deg),
                ],
                "contact",
            )
        )
    if s.plan is not None or s.planning is not None:
        rows: list[tuple[str, object]] = []
        if s.planning is not None:
            rows += [("contact used", s.planning.contact_used), ("contacts refused", len(s.planning.refusals))]
            rows += [(f"refusal {i + 1}", r) for i, r in enumerate(s.planning.refusals)]
        if s.plan is not None:
            p = s.plan
            rows += [
                ("plan id", p.plan_id),
                ("mode", p.mode),
                ("duration", f"{p.duration_s:.2f} s"),
                ("samples", p.samples),
                ("gate", "passed" if p.gate_ok else "FAILED"),
                ("peak joint speed [rad/s]", [round(v, 2) for v in p.peak_joint_speed_rad_s]),
                ("clearance bound", _mm(p.min_clearance_m)),
            ]
        if s.confirmation is not None:
            rows += [("confirmed by", s.confirmation.source), ("approved", s.confirmation.approved)]
        out.append(_kv_table("Plan", rows, "plan"))
    if s.verification is not None:
        v = s.verification
        rows = [("verified", v.ok), ("reason", v.reason)]
        if s.achieved_motion is not None:
            rows.append(("measured by", s.achieved_motion.method))
        if v.comparison is not None:
            rows += [(k, val) for k, val in v.comparison.model_dump(mode="json").items()]
        out.append(_kv_table("Verification", rows, "verification"))
    if s.sim_truth is not None:
        t = s.sim_truth
        moved = {k: f"{1000 * d:.0f} mm" for k, d in t.object_displacement_m.items()}
        rows = [
            ("target (moved most)", t.target),
            ("its centre from the goal", _mm(t.target_goal_error_m)),
            ("objects moved", moved),
            ("hinges [deg]", {k: round(a, 1) for k, a in t.hinge_deg.items()}),
        ]
        out.append(_kv_table("Simulator truth (never used to decide)", rows, "sim-truth"))
    if s.stage_seconds:
        out.append(_kv_table("Seconds per stage", [(k, f"{v:.2f} s") for k, v in s.stage_seconds.items()], "stages"))
    return out


def _execution_table(s: RunSummary) -> str:
    if not s.execution:
        return ""
    return _grid_table(
        "Execution",
        ["phase", "status", "ticks", "late", "jitter p99", "max tracking error", "gripper"],
        [
            (
                e.phase,
                e.status if e.status == "completed" else f"{e.status}: {e.reason}",
                e.ticks,
                e.late_ticks,
                f"{1000 * e.jitter_p99_s:.2f} ms",
                f"{np.degrees(e.max_tracking_error_rad):.2f} deg",
                "; ".join(
                    f"{g.kind} {_mm(g.width_m)}"
                    + ("" if g.grasped is None else (" grasped" if g.grasped else " EMPTY"))
                    for g in e.gripper
                )
                or "-",
            )
            for e in s.execution
        ],
        "execution",
    )


def render_report(summary: RunSummary, plots: Sequence[tuple[str, str]] = ()) -> str:
    """The page; `plots` are (file name beside the report, caption), drawn in that order."""
    s = summary
    colour = STATUS_COLOURS.get(s.status, "#555")
    meta = [
        f"profile {s.profile}" if s.profile else "",
        f"scene {s.scene}" if s.scene else "",
        f"seed {s.seed}" if s.seed is not None else "",
        f"{s.wall_s:.1f} s" if s.wall_s is not None else "",
        f"robot id {s.robot_id}" if s.robot_id else "",
    ]
    figures = "".join(
        f'<figure><a href="{_e(n)}"><img src="{_e(n)}" alt="{_e(n)}"></a><figcaption>{_e(n.rsplit(".", 1)[0])}'
        "</figcaption></figure>"
        for n in s.images
    )
    plot_html = "".join(
        f'<h2>{_e(caption)}</h2><img class="plot" src="{_e(name)}" alt="{_e(caption)}">' for name, caption in plots
    )
    transitions = _grid_table(
        "Transitions", ["from", "to", "reason"], [(t.previous, t.state, t.reason) for t in s.transitions], "transitions"
    )
    raw = html.escape(json.dumps(s.model_dump(mode="json"), indent=2))
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>goalvla run {_e(s.run_id)}: {_e(s.status)}</title>
<style>{STYLE}.status{{color:{colour}}}</style></head><body>
<h1>Run {_e(s.run_id)}</h1>
<div class="verdict"><span class="status" id="status">{_e(s.status)}</span>
<span class="meta">{_e(VERDICT_WORDS.get(s.status, ""))}</span></div>
<p class="reason" id="reason">{_e(s.reason)}</p>
<p><b>Instruction:</b> <span id="instruction">{_e(s.instruction)}</span><br>
<span class="meta">{_e(" · ".join(m for m in meta if m))}</span></p>
<div class="pictures" id="pictures">{figures}</div>
{plot_html}
<div class="tables">{"".join(_tables(s))}</div>
{_execution_table(s)}
{transitions}
<details id="raw"><summary>Raw summary.json (<a href="summary.json">file</a>)</summary><pre>{raw}</pre></details>
</body></html>
"""
