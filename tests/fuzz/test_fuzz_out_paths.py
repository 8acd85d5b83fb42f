"""Output paths that cannot be written (a directory where a file goes, a file where a folder goes, a path below a
file) are refused with exit 2 before any work: nothing is captured, moved or computed for nothing."""

from __future__ import annotations

import pytest
from fuzz_harness import assert_refused, run_cli


@pytest.fixture
def paths(tmp_path):
    (tmp_path / "file").write_text("")
    (tmp_path / "folder.pdf").mkdir()
    return tmp_path


@pytest.mark.parametrize(
    ("command", "out", "words"),
    [
        (["capture"], "file", ["capture folder", "not a folder"]),
        (["capture"], "file/below", ["not a directory"]),
        (["demo"], "file", ["demo folder", "not a folder"]),
        (["calibrate", "board"], "folder.pdf", ["board image", "a directory"]),
        (["calibrate", "board"], "file/board.pdf", ["not a directory"]),
        (["calibrate", "hand-eye", "--mode", "eye-to-hand"], "folder.pdf", ["calibration file", "a directory"]),
    ],
)
def test_unwritable_out_exits_2_before_work(paths, sim_config_path, command, out, words):
    config = [] if command == ["calibrate", "board"] else ["--config", sim_config_path]
    outcome = run_cli([*command, *config, "--out", paths / out])
    assert_refused(outcome, *words)
