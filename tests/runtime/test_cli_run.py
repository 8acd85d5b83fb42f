"""`goalvla run` contracts: argument errors exit 2; a run writes DIR/summary.json and its exit code follows the
status (0 only for a verified DONE)."""

from __future__ import annotations

import pytest
from runtime_helpers import free_port
from typer.testing import CliRunner

from runtime.commands.cli import app
from runtime.commands.launch import EXIT_CODES
from runtime.run.summary import RunSummary
from runtime.supervision.states import State

runner = CliRunner()


def test_instruction_or_serve_is_required(sim_config_path):
    result = runner.invoke(app, ["run", "--config", str(sim_config_path)])
    assert result.exit_code == 2 and "--instruction" in result.output


def test_scene_on_a_hardware_profile_is_refused(sim_config_path):
    lab = sim_config_path.parent / "lab.yaml"
    result = runner.invoke(app, ["run", "--config", str(lab), "--instruction", "x", "--scene", "tabletop"])
    assert result.exit_code == 2 and "only apply to sim profiles" in result.output


@pytest.mark.slow
def test_a_verified_run_exits_0_with_its_record(sim_config_path, tmp_path):
    profile = tmp_path / "p.yaml"
    profile.write_text(f"include: {sim_config_path}\nruntime: {{zenoh: {{endpoint: tcp/127.0.0.1:{free_port()}}}}}\n")
    args = ["run", "--config", str(profile), "--instruction", "put the red block on the white plate", "--yes"]
    result = runner.invoke(app, [*args, "--seed", "4", "--record", str(tmp_path / "run")])
    summary = RunSummary.model_validate_json((tmp_path / "run" / "summary.json").read_text())
    assert summary.seed == 4 and summary.instruction == "put the red block on the white plate"
    assert summary.status == "DONE" and result.exit_code == 0, (result.output, summary.reason)
    assert summary.verification.ok and summary.verification.comparison.position_error_m < 0.03
    # the verdict is the world's: the simulator's truth (recorded on a sim profile, never used to decide) agrees
    assert summary.sim_truth.target == "red_block" and summary.sim_truth.target_goal_error_m < 0.03
    assert (tmp_path / "run" / "report.html").exists() and (tmp_path / "run" / "capture.png").exists()


def test_exit_codes_follow_the_status():
    assert EXIT_CODES == {State.DONE: 0, State.FAILED: 1, State.ESTOPPED: 3}


def test_missing_api_key_stops_before_any_device_opens(sim_config_path, tmp_path, monkeypatch):
    monkeypatch.delenv("GEMINI_API_KEY", raising=False)
    profile = tmp_path / "p.yaml"
    profile.write_text(f"include: {sim_config_path}\npipeline: {{editor: gemini}}\n")
    result = runner.invoke(app, ["run", "--config", str(profile), "--instruction", "x", "--yes"])
    assert result.exit_code == 2 and "GEMINI_API_KEY" in result.output


@pytest.mark.parametrize("kind", ["earlier run", "file"])
def test_record_refuses_an_existing_run_folder_before_anything_runs(sim_config_path, tmp_path, kind):
    target = tmp_path / "run"
    if kind == "file":
        target.write_text("not a folder")
    else:
        target.mkdir()
        (target / "summary.json").write_text('{"status": "DONE"}')
    before = {p.name: p.read_bytes() for p in ([target] if target.is_file() else target.iterdir())}
    args = ["run", "--config", str(sim_config_path), "--instruction", "x", "--yes", "--record", str(target)]
    result = runner.invoke(app, args)
    assert result.exit_code == 2 and str(target) in result.output, result.output
    assert ("already holds files" if kind != "file" else "is not a folder") in result.output
    assert {p.name: p.read_bytes() for p in ([target] if target.is_file() else target.iterdir())} == before


def test_unstartable_runs_are_refused_before_any_device_opens(sim_config_path, tmp_path, monkeypatch):
    """A sentence outside the offline grammar (the grammar shown), a generated scene name that is no seed, and a
    scene whose objects overlap by their outlines (a pan's handle) all exit 2 before the simulator starts."""
    import runtime.commands.launch

    def must_not_start(*args, **kwargs):
        raise AssertionError("the run started")

    monkeypatch.setattr(runtime.commands.launch, "open_devices", must_not_start)
    base = ["run", "--config", str(sim_config_path), "--yes"]
    result = runner.invoke(app, [*base, "--instruction", "wipe the table"])
    assert result.exit_code == 2 and "not in the offline instruction grammar" in result.output
    assert "stand X up | stand up X" in result.output
    result = runner.invoke(app, [*base, "--instruction", "put the red block on the plate", "--scene", "gen:x"])
    assert result.exit_code == 2 and "gen:SEED" in result.output
    scene = tmp_path / "handle.yaml"
    scene.write_text(
        "name: handle\nobjects:\n"
        "  - {name: pan, kind: pan, radius_m: 0.08, color: gray, xy_m: [0.40, 0.0]}\n"
        "  - {name: tomato, kind: sphere, radius_m: 0.03, color: red, xy_m: [0.63, 0.0]}\n"
        "randomise: {xy_jitter_m: 0.0, yaw_jitter_deg: 0}\n"
    )
    result = runner.invoke(app, [*base, "--instruction", "put the red ball in the pan", "--scene", str(scene)])
    assert result.exit_code == 2 and "pan and tomato come within" in result.output
