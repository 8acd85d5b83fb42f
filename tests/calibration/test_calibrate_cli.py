"""`goalvla calibrate`: the board file, argument errors, and the hand-eye command's confirm/refuse paths."""

from __future__ import annotations

from rich.console import Console
from typer.testing import CliRunner

from calibration.board import load_board
from runtime.commands.calibrate import run_hand_eye
from runtime.commands.cli import app

runner = CliRunner()


def test_board_command_writes_a_printable_file(tmp_path):
    out = tmp_path / "board.pdf"
    result = runner.invoke(app, ["calibrate", "board", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.exists() and "240 x 180 mm" in result.output and "100 %" in result.output


def test_hand_eye_rejects_an_unknown_mode():
    result = runner.invoke(app, ["calibrate", "hand-eye", "--mode", "sideways"])
    assert result.exit_code == 2 and "eye-to-hand, eye-in-hand" in result.output


def test_declined_confirmation_moves_nothing_and_writes_nothing(sim_profile_with, tmp_path, monkeypatch):
    moved = []
    from drivers.sim.arm import SimArm

    monkeypatch.setattr(SimArm, "servo", lambda self, q: moved.append(q))
    questions = []
    out = tmp_path / "cal.yaml"
    profile = sim_profile_with({"calibration": {"hand_eye": {"poses": 6, "min_views": 6}}})
    code = run_hand_eye(
        profile,
        lambda overrides: sim_profile_with({"calibration": {"hand_eye": {"poses": 6, "min_views": 6}}, **overrides}),
        load_board("configs/boards/charuco_8x6_30mm.yaml"),
        "eye_to_hand",
        out,
        lambda q: questions.append(q) or False,
        Console(width=120),
    )
    assert code == 3 and not out.exists() and moved == []
    assert "6 views" in questions[0] and "e-stop" in questions[0]
