"""`goalvla estop` as a process: liveliness token, ~20 Hz heartbeats, an e-stop per key, one more on end of input."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest
from runtime_helpers import wait_for

from runtime.messaging.bus import Bus
from runtime.messaging.messages import EStop, Heartbeat

pytestmark = pytest.mark.slow


def test_terminal_node_beats_and_stops(runtime_cfg, tmp_path, sim_config_path):
    profile = tmp_path / "p.yaml"
    profile.write_text(
        f"include: {sim_config_path}\nruntime: {{robot_id: {runtime_cfg.robot_id}, "
        f"zenoh: {{endpoint: '{runtime_cfg.zenoh.endpoint}'}}}}\n"
    )
    with Bus(runtime_cfg.zenoh, runtime_cfg.robot_id, "listen") as hub:
        beats, stops, alive = [], [], []
        hub.subscribe(f"{hub.keys.heartbeat}/**", Heartbeat, lambda k, m: beats.append(time.monotonic()))
        hub.subscribe(hub.keys.estop, EStop, lambda k, m: stops.append(m))
        hub.watch_liveliness(f"{hub.keys.alive}/estop/**", lambda k, a: alive.append(a))
        cmd = [sys.executable, "-m", "runtime.commands.cli", "estop", "--config", str(profile), "--node", "pendant"]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        try:
            assert wait_for(lambda: len(beats) > 25, 20)  # ~1 s of heartbeats once connected
            recent = [t for t in beats if t > beats[-1] - 1.0]
            assert 12 <= len(recent) <= 25, f"{len(recent)} heartbeats in the last second"
            assert alive and alive[-1] is True
            proc.stdin.write("x")
            proc.stdin.flush()
            assert wait_for(lambda: len(stops) == 1, 5)
            assert stops[0].source == "pendant" and stops[0].reason == "e-stop key pressed"
            proc.stdin.close()  # end of input: one more e-stop, then the node quits and its token vanishes
            assert proc.wait(10) == 0
            assert wait_for(lambda: len(stops) == 2 and alive[-1] is False, 5)
            assert stops[1].reason == "e-stop node input closed"
        finally:
            proc.kill()
