"""Simulation speed: milliseconds to render one RGB-D frame (colour + aligned depth + sensor model) at the
default and full Femto Bolt colour resolutions, and the physics speed relative to real time.

    python bench/sim.py [--quick] --out RESULT.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

# bench/safety.py is named like the safety package: keep this folder off the import path
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from rich.console import Console  # noqa: E402
from rich.table import Table  # noqa: E402

from drivers.sim import SimCamera, SimWorld  # noqa: E402
from runtime.config import load_profile  # noqa: E402

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "sim.yaml"
TARGETS = {"rgbd_ms_640x360": 150.0, "physics_realtime_factor": 5.0}


def render_ms(width: int, height: int, frames: int) -> float:
    profile = load_profile(CONFIG, {"sim": {"realtime": False}, "camera": {"width_px": width, "height_px": height}})
    world = SimWorld(profile.sim, profile.camera)
    times = []
    with SimCamera(world) as camera:
        camera.read()  # first frame builds the GL context
        for _ in range(frames):
            world.step(1.0 / profile.camera.fps)
            t0 = time.perf_counter()
            camera.read()
            times.append((time.perf_counter() - t0) * 1e3)
    return float(np.median(times))


def physics_factor(seconds: float) -> float:
    profile = load_profile(CONFIG, {"sim": {"realtime": False}})
    world = SimWorld(profile.sim, profile.camera)
    t0 = time.perf_counter()
    world.step(seconds)
    return seconds / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer frames")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    frames = 5 if args.quick else 30
    result = {
        "rgbd_ms_640x360": render_ms(640, 360, frames),
        "rgbd_ms_1280x720": render_ms(1280, 720, frames),
        "physics_realtime_factor": physics_factor(2.0 if args.quick else 10.0),
        "frames": frames,
    }
    met = {
        "rgbd_ms_640x360": result["rgbd_ms_640x360"] <= TARGETS["rgbd_ms_640x360"],
        "physics_realtime_factor": result["physics_realtime_factor"] >= TARGETS["physics_realtime_factor"],
    }
    result |= {"targets": TARGETS, "met": met}
    table = Table(title="simulation speed")
    for column in ("measure", "value", "target", "met"):
        table.add_column(column)
    for key in ("rgbd_ms_640x360", "rgbd_ms_1280x720", "physics_realtime_factor"):
        target = TARGETS.get(key)
        table.add_row(key, f"{result[key]:.1f}", "" if target is None else f"{target:g}", str(met.get(key, "")))
    Console().print(table)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
