"""Profiles (--config) under bad YAML: every file loads into a profile whose floats are all finite and whose
physical values are in range, or is refused with exit 2 naming the file, the key (and line) and the problem;
never a traceback, a hang or 1 GB, whatever the YAML does (duplicate keys, aliases, nesting, tags, includes)."""

from __future__ import annotations

import json

import pytest
from fuzz_harness import assert_refused, load_profile_bounded, run_cli
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from payloads import ALIAS_BOMB, corrupted, dumps, valid_trajectory, yaml_number
from pydantic import BaseModel

from runtime.config import Profile

fuzz = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _key_paths(model: type[BaseModel], prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """Every key a profile may set, sections included."""
    out = []
    for name, field in model.model_fields.items():
        path = (*prefix, name)
        out.append(path)
        for sub in (field.annotation, *getattr(field.annotation, "__args__", ())):
            if isinstance(sub, type) and issubclass(sub, BaseModel):
                out += _key_paths(sub, path)
    return out


KEY_PATHS = _key_paths(Profile)
yaml_values = st.one_of(
    st.floats(0.001, 1.0).map(repr),
    st.integers(0, 100).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(yaml_number),
    st.sampled_from(["1e-300", "1e300", "-1e300", "0", "-1", "1e-9", "1e400", "9" * 41, "9" * 5000, "-0.0"]),
    st.sampled_from(["null", "true", "[]", "{}", "[.nan, .nan, .nan]", "[1e300, 0, 0]", '"~nobody/x"', '"\\0"']),
    st.sampled_from(["[0, 0, 0]", "[-1e9, -1e9, -1e9]", "{name: x, min_m: [0, 0, 0], max_m: [.nan, 1, 1]}"]),
    st.text(max_size=10).map(json.dumps),
)


def nested(path: tuple[str, ...], value: str) -> str:
    return (
        "".join(f"{'  ' * i}{key}:\n" for i, key in enumerate(path[:-1]))
        + f"{'  ' * (len(path) - 1)}{path[-1]}: {value}\n"
    )


@st.composite
def profile_texts(draw, base: str) -> bytes:
    """The default profile included, then one to three keys set to values of any type and magnitude, and
    sometimes a YAML attack on top."""
    settings_ = [nested(draw(st.sampled_from(KEY_PATHS)), draw(yaml_values)) for _ in range(draw(st.integers(1, 3)))]
    text = f"include: {base}\n" + "".join(settings_)
    attack = draw(st.sampled_from(["none", "none", "bytes", "duplicate", "alias", "deep", "tag"]))
    if attack == "duplicate":
        text += draw(st.sampled_from(settings_))
    elif attack == "alias":
        text += ALIAS_BOMB + "\n"
    elif attack == "deep":
        text += "x: " + "[" * draw(st.sampled_from([40, 5000, 100_000])) + "\n"
    elif attack == "tag":
        text += "robot: !!python/object/apply:os.system [echo owned]\n"
    data = text.encode()
    return draw(corrupted(data)) if attack == "bytes" else data


@pytest.fixture
def traj(tmp_path):
    path = tmp_path / "traj.json"
    path.write_bytes(dumps(valid_trajectory()))
    return path


@fuzz
@given(data=st.data())
def test_any_profile_loads_finite_or_is_refused(tmp_path, sim_config_path, data):
    path = tmp_path / "profile.yaml"
    path.write_bytes(data.draw(profile_texts(sim_config_path)))
    verdict, detail = load_profile_bounded(path)
    event(verdict)
    if verdict == "loaded":
        assert detail == [], f"non-finite values accepted: {detail}"
    else:
        assert "profile.yaml" in detail or "sim.yaml" in detail, detail


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_profile_on_the_command_line_is_answered(tmp_path, sim_config_path, traj, data):
    path = tmp_path / "profile.yaml"
    path.write_bytes(data.draw(profile_texts(sim_config_path)))
    outcome = run_cli(["check-trajectory", "--config", path, "--trajectory", traj])
    assert outcome.traceback is None, outcome.traceback
    event(f"exit {outcome.exit_code}")
    if outcome.exit_code == 2:
        assert_refused(outcome)
        assert "profile.yaml" in outcome.output or "sim.yaml" in outcome.output, outcome.output
    else:
        assert outcome.exit_code in (0, 3), outcome.output


PROFILE_CASES = {  # the families the issue lists: profile text after `include: sim.yaml` -> words of the refusal
    "NaN workspace": ("safety:\n  workspace: {min_m: [.nan, -1, 0], max_m: [1, 1, 1]}\n", ["safety.workspace.min_m.0"]),
    "inf workspace": ("safety:\n  workspace: {min_m: [-.inf, -1, 0], max_m: [1, 1, 1]}\n", ["safety.workspace"]),
    "workspace beyond the cell": ("safety:\n  workspace: {min_m: [-1e9, -1, 0], max_m: [1, 1, 1]}\n", ["min_m"]),
    "workspace not ordered": ("safety:\n  workspace: {min_m: [1, -1, 0], max_m: [0, 1, 1]}\n", ["below max_m"]),
    "NaN keep-out": ("safety:\n  keep_out: [{min_m: [0, 0, 0], max_m: [.nan, 1, 1]}]\n", ["safety.keep_out.0.max_m"]),
    "duplicate section": ("safety:\n  padding_m: 0.05\nsafety:\n  padding_m: 0.0\n", ["safety", "duplicate", ":4"]),
    "duplicate key": ("safety:\n  padding_m: 0.05\n  padding_m: 0.0\n", ["safety.padding_m", "duplicate", ":4"]),
    "resolution 1e-9": ("safety:\n  collision_resolution_rad: 1.0e-9\n", ["collision_resolution_rad"]),
    "step limit 1e300": ("safety:\n  max_joint_step_rad: 1.0e+300\n", ["max_joint_step_rad"]),
    "voxel 1e-9": ("safety:\n  cloud_voxel_m: 1.0e-9\n", ["cloud_voxel_m"]),
    "budget 1e308 s": ("runtime:\n  budgets_s: {planning: 1.0e+308}\n", ["runtime.budgets_s.planning"]),
    "5000-digit integer": ("sim:\n  seed: " + "9" * 5000 + "\n", ["5,000 characters"]),
    "negative seed": ("sim:\n  seed: -1\n", ["sim.seed"]),
    "nested 10^5 deep": ("x: " + "[" * 100_000 + "\n", ["nested"]),
    "alias bomb": (ALIAS_BOMB + "\n", ["aliases"]),
    "python tag": ("robot: !!python/object/apply:os.system [echo owned]\n", ["invalid YAML"]),
    "home of nobody": ('runtime:\n  runs_dir: "~nobody-here/x"\n', ["runtime.runs_dir"]),
    "NUL in a path": ('runtime:\n  runs_dir: "a\\0b"\n', ["runtime.runs_dir"]),
}


@pytest.mark.parametrize("case", list(PROFILE_CASES))
def test_listed_profile_families_exit_2(tmp_path, sim_config_path, traj, case):
    text, words = PROFILE_CASES[case]
    path = tmp_path / "profile.yaml"
    path.write_text(f"include: {sim_config_path}\n{text}")
    outcome = run_cli(["check-trajectory", "--config", path, "--trajectory", traj])
    assert_refused(outcome, "profile.yaml", *words)


def test_non_utf8_profile(tmp_path, traj):
    path = tmp_path / "profile.yaml"
    path.write_bytes(b"name: caf\xe9\n")
    assert_refused(run_cli(["check-trajectory", "--config", path, "--trajectory", traj]), "profile.yaml", "UTF-8")


@pytest.mark.parametrize(
    ("include", "words"),
    [
        ("profile.yaml", ["include cycle"]),
        ("/dev/zero", ["not a regular file"]),
        (".", ["a directory"]),
        ("missing.yaml", ["missing.yaml", "No such file"]),
        ('"a\\0b"', ["include"]),
        ("[fan.yaml, fan.yaml, fan.yaml, fan.yaml, fan.yaml, fan.yaml]", ["more than 32 files"]),
        ("{a: 1}", ["include"]),
    ],
)
def test_include_tricks_exit_2(tmp_path, traj, include, words):
    fan = tmp_path / "fan.yaml"
    fan.write_text("include: [fan2.yaml, fan2.yaml, fan2.yaml, fan2.yaml, fan2.yaml, fan2.yaml]\n")
    (tmp_path / "fan2.yaml").write_text("name: leaf\n")
    path = tmp_path / "profile.yaml"
    path.write_text(f"include: {include}\n")
    assert_refused(run_cli(["check-trajectory", "--config", path, "--trajectory", traj]), *words)
