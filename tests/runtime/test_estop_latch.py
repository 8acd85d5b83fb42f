"""The lasting e-stop latch file and `goalvla reset`."""

from __future__ import annotations

from typer.testing import CliRunner

from runtime.commands.cli import app
from runtime.supervision.estop_latch import EStopLatch


def test_latch_engages_reads_back_and_releases(tmp_path):
    latch = EStopLatch(tmp_path / "state" / "latch.json")
    assert latch.engaged() is None and latch.release("nobody") is None
    latch.engage("operator pressed E-STOP (from pendant)", stamp_s=1.7e9)
    latched = latch.engaged()
    assert latched.reason == "operator pressed E-STOP (from pendant)" and latched.stamp_s == 1.7e9
    assert "e-stop latched at" in latched.describe() and "pendant" in latched.describe()
    assert latch.release("test") == latched and latch.engaged() is None


def test_an_unreadable_latch_still_counts_as_engaged(tmp_path):
    path = tmp_path / "latch.json"
    path.write_text("{not json")
    latched = EStopLatch(path).engaged()
    assert latched is not None and "unreadable" in latched.reason


def profile_with_latch(tmp_path, sim_config_path, latch) -> str:
    config = tmp_path / "profile.yaml"
    config.write_text(f"include: {sim_config_path}\nruntime:\n  estop_latch_file: {latch}\n")
    return str(config)


def test_reset_command_asks_before_releasing(tmp_path, sim_config_path):
    latch = tmp_path / "latch.json"
    EStopLatch(latch).engage("deadman: no heartbeat for 0.25 s")
    config = profile_with_latch(tmp_path, sim_config_path, latch)
    runner = CliRunner()
    kept = runner.invoke(app, ["reset", "--config", config], input="n\n")
    assert kept.exit_code == 1 and "deadman" in kept.output and latch.exists()
    released = runner.invoke(app, ["reset", "--config", config], input="y\n")
    assert released.exit_code == 0 and "released" in released.output and not latch.exists()
    nothing = runner.invoke(app, ["reset", "--config", config, "--yes"])
    assert nothing.exit_code == 0 and "no e-stop latched" in nothing.output


def test_reset_command_without_a_latch_file_is_a_usage_error(sim_config_path):
    result = CliRunner().invoke(app, ["reset", "--config", str(sim_config_path), "--yes"])
    assert result.exit_code == 2 and "estop_latch_file is not set" in result.output
