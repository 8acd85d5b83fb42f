"""The operator console in headless Chromium (Debian's chromium driven by Playwright): a run on the sim is
started, confirmed, e-stopped and reset by clicking the page."""

from __future__ import annotations

import shutil
import socket
import threading
import time
import urllib.error
import urllib.request

import pytest
from runtime_helpers import free_port, wait_for
from scripted_stages import ScriptedStages

from runtime.commands.serve import serve
from runtime.config import load_profile
from runtime.devices import open_devices
from runtime.messaging.console.server import ConsoleServer
from runtime.messaging.messages import Status
from runtime.run.runner import Runtime
from runtime.sim_truth.oracle import GroundTruthGraspStages
from runtime.supervision.states import State

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
]
playwright = pytest.importorskip("playwright.sync_api", reason="pip install playwright (browsers are not downloaded)")
pytestmark = [pytest.mark.slow, pytest.mark.skipif(shutil.which("chromium") is None, reason="apt-get install chromium")]


def make_rig(sim_config_path, stages, runs_dir):
    runtime = {"zenoh": {"endpoint": f"tcp/127.0.0.1:{free_port()}"}, "robot_id": "console_test", "runs_dir": runs_dir}
    profile = load_profile(sim_config_path, {"runtime": runtime})
    stop = threading.Event()
    with open_devices(profile) as devices:
        rt = Runtime(profile, devices, stages, confirm="console")
        server = serve_in_thread(rt, stop)
        console = ConsoleServer(profile.runtime, "127.0.0.1", free_port()).start()
        try:
            yield rt, devices, stages, console
        finally:
            stop.set()
            server.join(5)
            console.close()
            rt.close()


@pytest.fixture
def rig(sim_config_path, tmp_path):
    yield from make_rig(sim_config_path, ScriptedStages(), str(tmp_path))


@pytest.fixture
def real_rig(sim_config_path, tmp_path):
    yield from make_rig(sim_config_path, GroundTruthGraspStages(), str(tmp_path))


def serve_in_thread(rt, stop):
    th = threading.Thread(target=serve, args=(rt, stop), daemon=True)
    th.start()
    return th


@pytest.fixture
def page():
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS, headless=True)
        yield new_page(browser)
        browser.close()


def new_page(browser, bypass_csp: bool = True):
    """A page in its own context; Playwright's wait_for_function evaluates strings, which the console's
    Content-Security-Policy forbids, so the tests that use it bypass the policy (one test keeps it)."""
    page = browser.new_page(bypass_csp=bypass_csp)
    page.set_default_timeout(20000)
    return page


def test_click_through_a_run_then_estop_and_reset(rig, page):
    rt, devices, stages, console = rig
    page.goto(console.url)
    page.wait_for_selector("#conn.ok")
    page.wait_for_function("document.getElementById('state').textContent === 'IDLE'")
    assert page.locator("#joints").inner_text() != "—"  # live telemetry arrives

    page.fill("#instruction", "move the arm a little")
    page.click("#run-btn")
    page.wait_for_selector("#confirm-btn:not([disabled])")
    plan_id = rt.status.plan_id
    assert plan_id and plan_id in page.locator("#confirm-btn").inner_text()
    assert plan_id in page.locator("#confirm-what").inner_text()
    assert "s," in page.locator("#plan-duration").inner_text() and "rad/s" in page.locator("#plan-speeds").inner_text()
    assert stages.streamed == 0  # nothing moves before the confirmation
    page.click("#confirm-btn")
    page.wait_for_function("document.getElementById('state').textContent === 'DONE'")
    assert stages.streamed > 0
    page.wait_for_function("document.getElementById('img-capture').naturalWidth > 0")

    stages.move_speed = 0.1  # a slow move, to press E-STOP during it
    page.click("#run-btn")
    page.wait_for_selector("#confirm-btn:not([disabled])")
    page.click("#confirm-btn")
    assert stages.executing.wait(10)
    page.click("#estop-btn")
    page.wait_for_function("document.getElementById('state').textContent === 'ESTOPPED'")
    assert "console E-STOP button" in page.locator("#reason").inner_text()
    assert rt.machine.state == State.ESTOPPED and devices.arm._stopped
    page.click("#reset-btn")
    page.wait_for_function("document.getElementById('state').textContent === 'IDLE'")
    assert wait_for(lambda: not rt.arm_halted)


def test_a_stalled_client_and_a_flood_leave_every_page_live(rig, page):
    """A client that stops reading its event stream, then 8000 status messages: the open page and one opened
    later still show the live state and can still stop the robot."""
    rt, _devices, _stages, console = rig
    page.goto(console.url)
    page.wait_for_function("document.getElementById('state').textContent === 'IDLE'")
    port = console.http.server_address[1]
    stalled = socket.socket()
    stalled.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    stalled.connect(("127.0.0.1", port))
    stalled.sendall(f"GET /events HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\r\n".encode())  # never read
    padding = "x" * 4000  # 32 MB in all: more than any socket buffers between here and a stalled client
    for i in range(8000):
        rt.bus.publish(rt.bus.keys.status, Status(stamp_s=time.time(), state="FLOOD", reason=f"flood {i} {padding}"))
    later = new_page(page.context.browser)
    later.goto(console.url)
    for p in (page, later):  # the runtime's own status (2 Hz) wins again on both
        p.wait_for_function("document.getElementById('state').textContent === 'IDLE'")
        p.wait_for_selector("#conn.ok")
    later.click("#estop-btn")
    page.wait_for_function("document.getElementById('state').textContent === 'ESTOPPED'")
    assert rt.machine.state == State.ESTOPPED
    stalled.close()


def test_the_page_works_under_its_content_security_policy(rig, page):
    _rt, _devices, _stages, console = rig
    strict = new_page(page.context.browser, bypass_csp=False)
    violations = []
    strict.on("console", lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None)
    strict.goto(console.url)
    strict.wait_for_selector("#conn.ok")
    strict.wait_for_selector("#state:has-text('IDLE')")
    assert violations == []


def test_posts_without_the_console_header_are_refused(rig):
    rt, _devices, _stages, console = rig
    req = urllib.request.Request(console.url + "api/estop", data=b"{}", method="POST")
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(req, timeout=5)
    assert err.value.code == 403
    assert rt.machine.state == State.IDLE


def test_a_real_pipeline_run_shows_every_picture(real_rig, page):
    """Reasoning, grounding, planning, execution and verification for real (contact from runtime.sim_truth.oracle)."""
    console = real_rig[3]
    page.goto(console.url)
    page.wait_for_selector("#conn.ok")
    page.fill("#instruction", "put the red block on the white plate")
    page.click("#run-btn")
    page.wait_for_selector("#confirm-btn:not([disabled])", timeout=60000)
    assert "grasp" in page.locator("#plan-mode").inner_text()
    assert "gate padding" in page.locator("#plan-clearance").inner_text()
    page.click("#confirm-btn")
    page.wait_for_function(
        "['DONE', 'FAILED', 'ESTOPPED'].includes(document.getElementById('state').textContent)", timeout=60000
    )
    assert page.locator("#state").inner_text() == "DONE", page.locator("#reason").inner_text()
    for name in ("capture", "goal", "overlay", "masks", "plan", "after"):
        page.wait_for_function(f"document.getElementById('img-{name}').naturalWidth > 0")
