"""The run record: one folder per run with summary.json, the images and report.html, mirrored on the bus.

Everything a stage decided goes through here, so a failed run can be understood from its folder alone and the
console sees the same images the folder keeps.
"""

from __future__ import annotations

import html
import json
import logging
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from runtime.messaging.bus import Bus
from runtime.supervision.states import Transition

log = logging.getLogger(__name__)

PUBLISHED_JPEG_QUALITY = 85


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


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


class RunRecord:
    def __init__(self, run_dir: Path, run_id: str, bus: Bus | None = None) -> None:
        self.dir = run_dir
        self.dir.mkdir(parents=True, exist_ok=True)
        self.run_id = run_id
        self.bus = bus
        self.summary: dict[str, Any] = {"run_id": run_id, "status": "RUNNING", "reason": "", "stage_seconds": {}}
        self.transitions: list[dict] = []
        self.images: list[str] = []
        self._t0 = time.monotonic()

    def on_transition(self, t: Transition) -> None:
        if t.previous.value not in ("IDLE", "DONE", "FAILED", "ESTOPPED"):
            key = t.previous.value.lower()
            self.summary["stage_seconds"][key] = round(
                self.summary["stage_seconds"].get(key, 0.0) + t.seconds_in_previous, 4
            )
        self.transitions.append(
            {"from": t.previous.value, "to": t.state.value, "reason": t.reason, "stamp_s": t.stamp_s}
        )

    def note(self, **fields: Any) -> None:
        self.summary.update(fields)

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
        self.summary.update(
            status=status,
            reason=reason,
            wall_s=round(time.monotonic() - self._t0, 3),
            transitions=self.transitions,
            images=[f"{n}.png" for n in self.images],
        )
        path = self.dir / "summary.json"
        path.write_text(json.dumps(self.summary, indent=2, default=_json_default))
        (self.dir / "report.html").write_text(render_report(self.summary))
        return path


def _rows(mapping: dict) -> str:
    return "".join(
        f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(json.dumps(v, default=_json_default))}</td></tr>"
        for k, v in mapping.items()
    )


def render_report(summary: dict) -> str:
    """A self-contained page (images referenced next to it) that a person can open from the run folder."""
    status = summary.get("status", "?")
    colour = {"DONE": "#1a7f37", "FAILED": "#b35900", "ESTOPPED": "#c00"}.get(status, "#555")
    skip = {"transitions", "images", "stage_seconds"}
    details = {k: v for k, v in summary.items() if k not in skip}
    transitions = "".join(
        f"<tr><td>{html.escape(t['from'])}</td><td>{html.escape(t['to'])}</td><td>{html.escape(t['reason'])}</td></tr>"
        for t in summary.get("transitions", [])
    )
    figures = "".join(
        f'<figure><img src="{html.escape(name)}" alt="{html.escape(name)}"><figcaption>{html.escape(name)}'
        "</figcaption></figure>"
        for name in summary.get("images", [])
    )
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>goalvla run {html.escape(str(summary.get("run_id", "")))}</title>
<style>body{{font-family:sans-serif;margin:2em;max-width:1200px}} table{{border-collapse:collapse;margin:1em 0}}
td,th{{border:1px solid #ccc;padding:4px 8px;text-align:left;vertical-align:top;font-size:13px}}
figure{{display:inline-block;margin:4px}} img{{max-width:380px}} .status{{color:{colour};font-size:1.6em}}</style>
</head><body>
<h1>Run {html.escape(str(summary.get("run_id", "")))}</h1>
<p class="status" id="status">{html.escape(status)}</p><p id="reason">{html.escape(str(summary.get("reason", "")))}</p>
<h2>Instruction</h2><p>{html.escape(str(summary.get("instruction", "")))}</p>
<h2>Seconds per stage</h2><table>{_rows(summary.get("stage_seconds", {}))}</table>
<h2>Transitions</h2><table><tr><th>from</th><th>to</th><th>reason</th></tr>{transitions}</table>
<h2>Images</h2>{figures}
<h2>Details</h2><table>{_rows(details)}</table>
</body></html>
"""
