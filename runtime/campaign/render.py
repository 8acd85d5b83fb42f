"""The campaign table as people read it: a rich table on the terminal, markdown for a paper or an issue, and a
small HTML page linking each run's report."""

from __future__ import annotations

import html

from rich.table import Table

from runtime.campaign.results import CampaignTable, CaseResult, Row

COLUMNS = (
    "runs",
    "verified",
    "success",
    "done (sim)",
    "false succ.",
    "false fail.",
    "load stops",
    "failed in",
    "median",
)
LEGEND = (
    "done (sim): the simulator's truth of where the target ended and how it is turned (never used by the run); "
    "false succ.: verified but not done; false fail.: done but not verified; load stops: runs this machine's load "
    "stopped (a starved simulated robot or e-stop heartbeat); failed in: the state where a run that was not "
    "verified ended; median: the runs' median wall time."
)


def _cells(row: Row) -> list[str]:
    failed = ", ".join(f"{stage} {n}" for stage, n in row.failed_in.items()) or "-"
    unknown = f" ({row.truth_unknown} unknown)" if row.truth_unknown else ""
    return [
        str(row.runs),
        str(row.verified),
        f"{100 * row.success_rate:.0f} %",
        f"{row.truly_done}{unknown}",
        str(row.false_successes),
        str(row.false_failures),
        str(row.load_faults),
        failed,
        "-" if row.median_wall_s is None else f"{row.median_wall_s:.1f} s",
    ]


def _sections(table: CampaignTable) -> list[tuple[str, list[Row]]]:
    return [("task", [*table.by_task, table.total]), ("action", table.by_action)]


def rich_tables(table: CampaignTable, title: str) -> list[Table]:
    out = []
    for label, rows in _sections(table):
        t = Table(title=f"{title}: by {label}")
        t.add_column(label)
        for c in COLUMNS:
            t.add_column(c, justify="left" if c == "failed in" else "right")
        for row in rows:
            t.add_row(row.group, *_cells(row), style="bold" if row is table.total else None)
        out.append(t)
    return out


def markdown(table: CampaignTable, title: str) -> str:
    lines = [f"# {title}", ""]
    for label, rows in _sections(table):
        lines += [f"## By {label}", "", f"| {label} | " + " | ".join(COLUMNS) + " |"]
        lines.append("|" + " --- |" * (len(COLUMNS) + 1))
        lines += [f"| {row.group} | " + " | ".join(_cells(row)) + " |" for row in rows]
        lines.append("")
    lines.append(LEGEND)
    return "\n".join(lines) + "\n"


def html_page(table: CampaignTable, title: str, results: list[CaseResult], subtitle: str = "") -> str:
    def grid(label: str, rows: list[Row]) -> str:
        head = "".join(f"<th>{html.escape(c)}</th>" for c in (label, *COLUMNS))
        body = "".join(
            ('<tr class="total">' if row is table.total else "<tr>")
            + "".join(f"<td>{html.escape(c)}</td>" for c in (row.group, *_cells(row)))
            + "</tr>"
            for row in rows
        )
        return f"<h2>By {html.escape(label)}</h2><table><tr>{head}</tr>{body}</table>"

    runs = "".join(
        f'<tr><td><a href="runs/{html.escape(r.case.id)}/report.html">{html.escape(r.case.id)}</a></td>'
        f"<td>{html.escape(r.case.instruction)}</td><td>{html.escape(r.status)}</td>"
        f"<td>{'-' if r.truly_done is None else ('yes' if r.truly_done else 'no')}</td>"
        f"<td>{html.escape(r.reason[:160])}</td></tr>"
        for r in sorted(results, key=lambda r: r.case.id)
    )
    return f"""<!doctype html><html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:system-ui,sans-serif;margin:1.5em auto;max-width:1180px;padding:0 1em}}
table{{border-collapse:collapse;margin:.5em 0 1.5em}} td,th{{border:1px solid #ccc;padding:3px 8px;font-size:13px;
text-align:left}} th{{background:#f4f4f4}} tr.total td{{font-weight:bold}} .sub{{color:#555}}</style></head>
<body><h1>{html.escape(title)}</h1><p class="sub">{html.escape(subtitle)}</p>
{"".join(grid(label, rows) for label, rows in _sections(table))}<p>{html.escape(LEGEND)}</p>
<h2>Runs</h2><table><tr><th>run</th><th>instruction</th><th>status</th><th>done (sim)</th><th>reason</th></tr>
{runs}</table></body></html>
"""
