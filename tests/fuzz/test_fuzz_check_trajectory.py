"""`goalvla check-trajectory` under bad TRAJ.json, WORLD.json and points files: every case ends with exit 0 or 3
and a JSON report, or exit 2 naming the file and the problem; never a traceback, a hang or more than 1 GB."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from fuzz_harness import CliOutcome, assert_refused, run_cli
from hypothesis import HealthCheck, event, given, settings
from payloads import (
    declared_npz,
    dumps,
    huge_header_npz,
    many_members_npz,
    npz_bytes,
    npz_files,
    repeated_member_npz,
    trajectory_files,
    valid_trajectory,
    world_files,
)

fuzz = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def check(config, traj, world=None) -> CliOutcome:
    args = ["check-trajectory", "--config", config, "--trajectory", traj]
    return run_cli(args + (["--world", world] if world else []))


def assert_handled(outcome: CliOutcome, *files) -> None:
    """Exit 0/3 with a parseable report, or a refusal that names one of the files."""
    assert outcome.traceback is None, outcome.traceback
    event(f"exit {outcome.exit_code}")
    if outcome.exit_code in (0, 3):
        report = json.loads(outcome.output)
        assert report["ok"] is (outcome.exit_code == 0)
    else:
        assert_refused(outcome)
        assert any(os.path.basename(str(f)) in outcome.output for f in files), outcome.output


@pytest.fixture
def files(tmp_path, sim_config_path):
    class Files:
        config = sim_config_path
        traj = tmp_path / "traj.json"
        world = tmp_path / "world.json"
        cloud = tmp_path / "cloud.npz"

        def write(self, path, data: bytes):
            path.write_bytes(data)
            return path

    f = Files()
    f.write(f.traj, dumps(valid_trajectory()))
    return f


@fuzz
@given(data=trajectory_files())
def test_any_trajectory_file_is_answered(files, data):
    outcome = check(files.config, files.write(files.traj, data))
    assert_handled(outcome, files.traj)


@fuzz
@given(data=world_files())
def test_any_world_file_is_answered(files, data):
    outcome = check(files.config, files.traj, files.write(files.world, data))
    assert_handled(outcome, files.world)


@fuzz
@given(data=npz_files({"points": np.random.default_rng(0).uniform(-1, 1, (50, 3))}))
def test_any_points_file_is_answered(files, data):
    files.write(files.cloud, data)
    outcome = check(files.config, files.traj, files.write(files.world, dumps({"points_file": "cloud.npz"})))
    assert_handled(outcome, files.world)


TRAJ_CASES = {  # the families the issue lists, each named: content -> words the refusal must contain
    "not UTF-8": (b'{"joint_names": "\xff\xfe"}', ["not UTF-8", "offset"]),
    "5000-digit integer": (dumps(valid_trajectory()).replace(b"0.004", b"9" * 5000), ["5,000 characters"]),
    "nested 10^5 deep": (b"[" * 100_000 + b"]" * 100_000, ["nested 100000 levels"]),
    "empty": (b"", ["empty file"]),
    "truncated": (dumps(valid_trajectory())[:40], ["invalid JSON"]),
    "duplicate key": (b'{"dt": 1.0, ' + dumps(valid_trajectory())[1:], ["dt", "repeated"]),
    "NaN position": (dumps(valid_trajectory([[float("nan")] + [0.0] * 6])), ["positions.1.0", "finite"]),
    "dt of 1e300": (dumps(valid_trajectory([[0.0] * 7], dt=1e300)), ["dt"]),
    "absurd number of values": (b"[" + b"0," * 2_500_000 + b"0]", ["values"]),
}


@pytest.mark.parametrize("case", list(TRAJ_CASES))
def test_listed_trajectory_families_exit_2(files, case):
    content, words = TRAJ_CASES[case]
    assert_refused(check(files.config, files.write(files.traj, content)), "traj.json", *words)


@pytest.mark.parametrize("jump", [1e300, 1e6, -1.7e308])
def test_absurd_jumps_are_violations_found_without_subsampling(files, jump):
    doc = valid_trajectory([[jump] + [0.0] * 6, [0.0] * 7])
    outcome = check(files.config, files.write(files.traj, dumps(doc)))
    assert outcome.traceback is None and outcome.exit_code == 3, outcome.output
    report = json.loads(outcome.output)
    assert {"joint_limit", "step"} <= {v["kind"] for v in report["violations"]}
    assert report["configurations_checked"] == 3  # the jumps' ends only


def test_not_a_regular_file_or_missing(files, tmp_path):
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)  # opening it would block forever
    assert_refused(check(files.config, fifo), "fifo.json", "not a regular file")
    assert_refused(check(files.config, tmp_path), "a directory")
    assert_refused(check(files.config, tmp_path / "missing.json"), "missing.json", "No such file")
    big = tmp_path / "big.json"
    with big.open("wb") as f:
        f.truncate(64 * 2**20)  # sparse: 64 MiB of NUL on no disk
    assert_refused(check(files.config, big), "big.json", "more than")


POINTS_CASES = {
    "empty": (b"", "empty file"),
    "truncated": (npz_bytes({"points": np.zeros((100, 3))})[:300], "cannot read points file"),
    ".npy instead of .npz": (b"\x93NUMPY" + b"\x00" * 100, "single .npy array"),
    "zip bomb": (declared_npz({"points": ("<f8", (2**28, 3))}), "bytes allowed"),
    "pickled objects": (npz_bytes({"points": np.array([None, {}], dtype=object)}), "Python objects"),
    "wrong shape": (npz_bytes({"points": np.zeros((10, 4))}), "(N, 3)"),
    "NaN": (npz_bytes({"points": np.full((10, 3), np.nan)}), "NaN"),
    "far away": (npz_bytes({"points": np.full((10, 3), 1e300)}), "outside the cell"),
    "unknown key": (npz_bytes({"points": np.zeros((10, 3)), "colors": np.zeros(3)}), "colors"),
    "many members": (many_members_npz(5000), "members"),
    "huge header": (huge_header_npz("points"), "cannot read points file"),
    "repeated member": (repeated_member_npz("points", np.zeros((3, 3)), np.full((3, 3), 5.0)), "repeated"),
}


@pytest.mark.parametrize("case", list(POINTS_CASES))
def test_listed_points_file_families_exit_2(files, case):
    content, words = POINTS_CASES[case]
    files.write(files.cloud, content)
    world = files.write(files.world, dumps({"points_file": "cloud.npz"}))
    assert_refused(check(files.config, files.traj, world), "world.json", "points_file", "cloud.npz", words)


@pytest.mark.parametrize(
    ("world", "words"),
    [
        ({"boxes": [{"center": [1e300, 0, 0], "size": [0.1, 0.1, 0.1]}]}, ["boxes.0.center.0"]),
        ({"spheres": [{"center": [0, 0, 0.5], "radius": 1e38}]}, ["spheres.0.radius"]),
        ({"boxes": [{"center": [0.5, 0, 0.2], "size": [0.1, 0.1, 0.1]}] * 1001}, ["boxes"]),
        ({"gripper_width_m": 1e300}, ["gripper_width_m"]),
        ({"points_file": "\x00"}, ["points_file"]),
        ({"points_file": "."}, ["points_file", "a directory"]),
    ],
)
def test_absurd_world_numbers_exit_2(files, world, words):
    assert_refused(check(files.config, files.traj, files.write(files.world, dumps(world))), "world.json", *words)


@pytest.mark.slow
def test_a_trajectory_needing_too_many_checks_is_refused_in_bounded_time(files, tmp_path):
    """A profile at the finest resolution and 400 ticks of 5 rad: 2 million sub-samples, beyond the gate's
    work bound; it ends with an `unchecked` violation (exit 3) after at most that many checks."""
    profile = tmp_path / "fine.yaml"
    profile.write_text(f"include: {files.config}\nsafety: {{collision_resolution_rad: 0.001}}\n")
    rows = [[(5.0 if k % 2 else 0.0)] + [0.0] * 6 for k in range(1, 401)]
    outcome = check(profile, files.write(files.traj, dumps(valid_trajectory(rows))))
    assert outcome.traceback is None and outcome.exit_code == 3, outcome.output
    report = json.loads(outcome.output)
    assert "unchecked" in {v["kind"] for v in report["violations"]}
    assert report["configurations_checked"] == 1_000_000
