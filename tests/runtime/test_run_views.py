"""Looking at a run: one whole pipeline run on the sim leaves run.rrd (read back with Rerun's own Python API, every
listed entity in it, the robot's links moving), trajectories.npz and a report.html whose plots a headless Chromium
shows on the first screens, above the folded raw summary; `goalvla view` picks the web viewer without a display and
serves it on the loopback."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from runtime_helpers import free_port, sim_run_profile

from runtime.commands.view import ViewError, plan_view
from runtime.run.recording import ENTITIES
from runtime.run.trajectories import RunTrajectories

pytestmark = pytest.mark.slow
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory, sim_config_path):
    from runtime.devices import open_devices
    from runtime.run.runner import Runtime
    from runtime.run.stages import PipelineStages
    from runtime.sim_truth.listener import SimTruth

    out = tmp_path_factory.mktemp("views") / "run"
    profile = sim_run_profile(sim_config_path, "tabletop", 4, robot_id="views")
    with open_devices(profile) as devices, Runtime(profile, devices, PipelineStages([SimTruth()]), "yes") as rt:
        result = rt.run("put the red block on the white plate", out)
    executed = [p for p in result.summary.execution if p.ticks > 0]
    assert executed, f"the run never streamed ({result.reason}): nothing to look at"
    return out


def entity_paths(rrd: Path) -> set[str]:
    from rerun.chunk import RrdReader

    return {p.lstrip("/") for p in RrdReader(rrd).store().schema().entity_paths()}


def test_run_rrd_holds_every_listed_entity(run_dir):
    paths = entity_paths(run_dir / "run.rrd")
    needed = [
        "capture", "goal", "overlay", "masks", "camera", "scene_cloud", "target_initial", "target_goal",
        "object_motion", "pre_contact", "contact", "gripper_goal", "tcp_planned", "tcp_executed", "states", "gate",
        "tracking_error",
    ]  # fmt: skip
    assert [ENTITIES[n] for n in needed if ENTITIES[n] not in paths] == []
    joints = [f"joint{i}" for i in range(1, 8)]
    for kind in ("joints_planned", "joints_executed"):
        assert {f"{ENTITIES[kind]}/{j}" for j in joints} <= paths
    links = {f"{ENTITIES['robot']}/link{i}" for i in range(1, 8)} | {f"{ENTITIES['robot']}/link_tcp"}
    assert links <= paths, sorted(links - paths)
    assert any(p.startswith(f"{ENTITIES['robot']}/link7/shape_") for p in paths)  # the link's geometry


def test_the_robot_links_follow_the_measured_joints(run_dir):
    """link7's pose is logged over time (not once), and its positions span the motion the TCP made."""
    from rerun.chunk import RrdReader

    reader = RrdReader(run_dir / "run.rrd")
    path = f"/{ENTITIES['robot']}/link7"
    columns = reader.store().schema().columns_for(entity_path=path, archetype="rerun.archetypes.Transform3D")
    assert columns and not any(c.is_static for c in columns)
    translations = []
    for chunk in reader.stream():
        if chunk.entity_path == path and not chunk.is_static:
            batch = chunk.to_record_batch()
            name = next(n for n in batch.schema.names if n.endswith("Transform3D:translation"))
            translations += [row[0] for row in batch.column(name).to_pylist() if row]
    translations = np.array(translations)
    traj = RunTrajectories.load(run_dir)
    steps = sum(len(e.times_s) for e in traj.executed)
    assert len(translations) > 10 and len(translations) < steps  # sub-sampled, not one pose
    assert np.ptp(translations, axis=0).max() > 0.05  # it moved


def test_trajectories_file_reads_back(run_dir):
    traj = RunTrajectories.load(run_dir)
    assert traj.joint_names == tuple(f"joint{i}" for i in range(1, 8))
    assert traj.planned[0].name == "approach" and all(p.gate_ok for p in traj.planned)
    assert all(len(p.clearance) and np.all(np.isfinite(p.clearance)) for p in traj.planned)
    first = traj.executed[0]
    assert first.q_cmd.shape == first.q_meas.shape and first.q_cmd.shape[1] == 7
    # what was streamed is what was planned: the executor's set-points follow the approved trajectory
    assert np.abs(first.q_cmd[-1] - traj.planned[0].positions[-1]).max() < 1e-3 or first.status != "completed"


@pytest.mark.skipif(shutil.which("chromium") is None, reason="apt-get install chromium")
def test_report_shows_the_verdict_then_the_plots_in_chromium(run_dir, tmp_path):
    playwright = pytest.importorskip("playwright.sync_api")
    shot = tmp_path / "report.png"
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--headless", "--no-sandbox"], headless=True)
        page = browser.new_page(viewport={"width": 1280, "height": 2000})
        page.goto((run_dir / "report.html").as_uri())
        page.wait_for_load_state("load")
        status = page.locator("#status").bounding_box()
        plots = page.locator("img.plot")
        names = [plots.nth(i).get_attribute("src") for i in range(plots.count())]
        boxes = [plots.nth(i).bounding_box() for i in range(plots.count())]
        loaded = page.evaluate("[...document.querySelectorAll('img.plot')].map(i => i.complete && i.naturalWidth)")
        raw_open = page.evaluate("document.querySelector('#raw').open")
        raw_top = page.locator("#raw").bounding_box()["y"]
        tables = page.evaluate("[...document.querySelectorAll('table')].map(t => t.id)")
        page.screenshot(path=str(shot))
        browser.close()
    assert names == ["plot_timeline.png", "plot_joints.png", "plot_tracking.png", "plot_clearance.png"]
    assert all(loaded), loaded
    assert status["y"] < 100  # the verdict first
    assert not raw_open and all(b["y"] + b["height"] < raw_top for b in boxes)  # JSON folded, below the plots
    assert {"contact", "plan", "execution", "verification"} <= set(tables) or "verification" not in tables
    screen = np.asarray(Image.open(shot).convert("RGB")).astype(int)
    for name, box in zip(names, boxes, strict=True):
        x, y, w, h = (round(box[k]) for k in ("x", "y", "width", "height"))
        assert y + h <= screen.shape[0], f"{name} lies below the first 2000 px"
        crop = screen[y : y + h, x : x + w]
        drawn = np.asarray(Image.open(run_dir / name).convert("RGB").resize((w, h))).astype(int)
        assert np.abs(crop - drawn).mean() < 12, f"{name} is not what the screen shows"
        assert (np.abs(crop - 255).sum(axis=2) > 60).mean() > 0.02, f"{name} shows (almost) nothing"


def test_view_picks_the_web_viewer_without_a_display_and_serves_it_on_the_loopback(run_dir):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    web, grpc = free_port(), free_port()
    plan = plan_view(run_dir, env, web_port=web, grpc_port=grpc)
    assert plan.viewer == "web" and "--bind" in plan.command and plan.url.startswith(f"http://127.0.0.1:{web}/")
    assert plan_view(run_dir, {**env, "DISPLAY": ":0"}).viewer == "native"
    env["CI"] = "1"  # Rerun's viewer sends no usage data on CI
    proc = subprocess.Popen(plan.command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline, page = time.monotonic() + 60, None
        while page is None and time.monotonic() < deadline and proc.poll() is None:
            try:
                with urllib.request.urlopen(f"http://127.0.0.1:{web}/", timeout=2) as reply:
                    page = reply.status, reply.read(200)
            except OSError:
                time.sleep(0.2)  # the server is starting: poll its port (bounded by the deadline)
        assert page is not None and page[0] == 200, "the web viewer did not answer on the loopback"
        listening = Path("/proc/net/tcp").read_text().splitlines()[1:]
        local = {line.split()[1] for line in listening if line.split()[3] == "0A"}  # state LISTEN
        assert f"0100007F:{web:04X}" in local and f"00000000:{web:04X}" not in local  # 127.0.0.1 only
    finally:
        proc.terminate()
        proc.wait(10)


def test_view_refuses_a_folder_without_a_recording(tmp_path):
    with pytest.raises(ViewError, match=r"no run\.rrd"):
        plan_view(tmp_path, {})
    with pytest.raises(ViewError, match="not a run folder"):
        plan_view(tmp_path / "missing", {})


def test_goalvla_view_exits_2_naming_the_problem(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "runtime.commands.cli", "view", str(tmp_path)], capture_output=True, text=True
    )
    assert result.returncode == 2 and "no run.rrd" in result.stderr
