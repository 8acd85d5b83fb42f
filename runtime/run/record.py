"""The run record: one folder per run with summary.json, the images and report.html, mirrored on the bus.

Everything a stage decided goes into its section of the RunSummary (runtime.run.summary), so a failed run can be
understood from its folder alone, and every image through here, so the console sees the images the folder keeps.
"""

from __future__ import annotations

import html
import json
import logging
import os
import time
from pathlib import Path

import cv2
import numpy as np

from runtime.messaging.bus import Bus
from runtime.run.summary import RunSummary, TransitionRecord
from runtime.supervision.states import Transition

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

    def finish(self, status: str, reason: str) -> Path:
        summary = self.summary
        summary.status, summary.reason = status, reason
        summary.wall_s = round(time.monotonic() - self._t0, 3)
        summary.images = [f"{n}.png" for n in self.images]
        path = self.dir / "summary.json"
        path.write_text(summary.model_dump_json(indent=2))
        (self.dir / "report.html").write_text(render_report(summary))
        return path


def _rows(mapping: dict) -> str:
    return "".join(
        f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(json.dumps(v))}</td></tr>" for k, v in mapping.items()
    )


def render_report(summary: RunSummary) -> str:
    """A self-contained page (images referenced next to it) that a person can open from the run folder."""
    status = summary.status
    colour = {"DONE": "#1a7f37", "FAILED": "#b35900", "ESTOPPED": "#c00"}.get(status, "#555")
    details = summary.model_dump(mode="json", exclude={"transitions", "images", "stage_seconds"}, exclude_none=True)
    transitions = "".join(
        f"<tr><td>{html.escape(t.previous)}</td><td>{html.escape(t.state)}</td><td>{html.escape(t.reason)}</td></tr>"
        for t in summary.transitions
    )
    figures = "".join(
        f'<figure><img src="{html.escape(name)}" alt="{html.escape(name)}"><figcaption>{html.escape(name)}'
        "</figcaption></figure>"
        for name in summary.images
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>goalvla run {html.escape(summary.run_id)}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1200px}} table{{border-collapse:collapse;margin:1em 0}}
td,th{{border:1px solid #ccc;padding:4px 8px;text-align:left;vertical-align:top;font-size:13px}}
figure{{display:inline-block;margin:4px}} img{{max-width:380px}} .status{{color:{colour};font-size:1.6em}}</style>
</head><body>
<h1>Run {html.escape(summary.run_id)}</h1>
<p class="status" id="status">{html.escape(status)}</p><p id="reason">{html.escape(summary.reason)}</p>
<h2>Instruction</h2><p>{html.escape(summary.instruction)}</p>
<h2>Seconds per stage</h2><table>{_rows(summary.stage_seconds)}</table>
<h2>Transitions</h2><table><tr><th>from</th><th>to</th><th>reason</th></tr>{transitions}</table>
<h2>Images</h2>{figures}
<h2>Details</h2><table>{_rows(details)}</table>
</body></html>
"""
