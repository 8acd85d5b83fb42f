from pathlib import Path

import pytest

from runtime.config import ConfigError, load_profile

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_shipped_profiles_load_and_lab_overrides_sim():
    sim = load_profile(CONFIGS / "sim.yaml")
    lab = load_profile(CONFIGS / "lab.yaml")
    assert sim.robot.kind == "sim" and sim.camera.kind == "sim"
    assert lab.robot.kind == "xarm7" and str(lab.robot.ip) == "192.168.1.208"
    assert lab.camera.kind == "femto_bolt" and lab.camera.width_px == 1280
    # sections lab does not override come from sim.yaml
    assert lab.sim.scene == sim.sim.scene
    assert lab.safety.workspace == sim.safety.workspace
    # lab lowers speeds, within the vendor limits
    assert lab.safety.max_joint_velocity_rad_s < sim.safety.max_joint_velocity_rad_s
    # relative paths resolve against the file that wrote them
    assert lab.calibration.file == (CONFIGS / "calibration/lab_eye_to_hand.yaml").resolve()
    assert sim.sim.scene_file == (CONFIGS / "scenes/tabletop.yaml").resolve()


def test_include_overrides_only_the_keys_it_sets(tmp_path):
    write(tmp_path, "base.yaml", "camera:\n  width_px: 800\n  height_px: 600\nsafety:\n  padding_m: 0.03\n")
    child = write(tmp_path, "child.yaml", "include: base.yaml\ncamera:\n  width_px: 1024\n")
    p = load_profile(child)
    assert (p.camera.width_px, p.camera.height_px, p.safety.padding_m) == (1024, 600, 0.03)


def test_unknown_key_names_file_and_key_path(tmp_path):
    write(tmp_path, "base.yaml", "robot:\n  kind: sim\n")
    child = write(tmp_path, "child.yaml", "include: base.yaml\ncamera:\n  sim:\n    fov: 70\n")
    with pytest.raises(ConfigError) as e:
        load_profile(child)
    assert f"{child.resolve()}: camera.sim.fov: unknown key" in str(e.value)


def test_error_is_attributed_to_the_included_file_that_set_the_value(tmp_path):
    base = write(tmp_path, "base.yaml", "camera:\n  width_px: 10\n")
    child = write(tmp_path, "child.yaml", "include: base.yaml\nrobot:\n  kind: sim\n")
    with pytest.raises(ConfigError) as e:
        load_profile(child)
    assert f"{base.resolve()}: camera.width_px: Input should be greater than or equal to 64" in str(e.value)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("robot:\n  kind: xarm7\n", "robot: robot.kind 'xarm7' needs robot.ip"),
        ("robot:\n  kind: xarm7\n  ip: 300.1.2.3\n", "robot.ip: Input is not a valid IPv4 address"),
        ("safety:\n  max_joint_velocity_rad_s: 5.0\n", "exceeds the vendor limit 3.142"),
        ("camera:\n  min_depth_m: 4\n  max_depth_m: 3\n", "min_depth_m 4.0 must be below max_depth_m 3.0"),
        ("robot:\n  home_q_rad: [0, 0, 0]\n", "robot.home_q_rad"),
        ("sim:\n  physics_dt_s: 0.5\n", "sim.physics_dt_s: Input should be less than or equal to 0.01"),
    ],
)
def test_invalid_values_are_readable(tmp_path, text, expected):
    path = write(tmp_path, "p.yaml", text)
    with pytest.raises(ConfigError) as e:
        load_profile(path)
    assert expected in str(e.value)
    assert str(path.resolve()) in str(e.value)


def test_yaml_syntax_error_gives_line(tmp_path):
    path = write(tmp_path, "p.yaml", "robot:\n  kind: [sim\n")
    with pytest.raises(ConfigError, match=r"p\.yaml:\d+:\d+: invalid YAML"):
        load_profile(path)


def test_include_cycle_and_missing_include(tmp_path):
    write(tmp_path, "a.yaml", "include: b.yaml\n")
    write(tmp_path, "b.yaml", "include: a.yaml\n")
    with pytest.raises(ConfigError, match="include cycle"):
        load_profile(tmp_path / "a.yaml")
    missing = write(tmp_path, "c.yaml", "include: nope.yaml\n")
    with pytest.raises(ConfigError, match=r"nope\.yaml: cannot read profile"):
        load_profile(missing)


def test_top_level_must_be_a_mapping(tmp_path):
    with pytest.raises(ConfigError, match="must be a mapping"):
        load_profile(write(tmp_path, "p.yaml", "- robot\n"))


def test_command_line_overrides_win(sim_config_path):
    p = load_profile(sim_config_path, {"sim": {"seed": 7, "realtime": False}})
    assert p.sim.seed == 7 and p.sim.realtime is False
