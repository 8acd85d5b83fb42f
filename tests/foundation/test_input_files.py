"""drivers.files: every YAML reader refuses a repeated key by name and line; the JSON and NPZ readers measure
before they build (nesting, values, declared array sizes)."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from calibration.board import BoardError, load_board
from calibration.store import CalibrationError, load_calibration
from drivers.files import InputFileError, load_json, load_yaml, read_npz
from drivers.sim.scene import SceneError, load_scene
from runtime.config import ConfigError, load_profile

BOARD = "name: b\nsquares_x: 8\nsquares_y: 6\nsquare_length_m: 0.03\nmarker_length_m: 0.022\n"
READERS = {  # text with a key set twice at line 3 (first at line 2), the reader, its error
    "profile": ("name: x\nsafety: {padding_m: 0.05}\nsafety: {padding_m: 0.0}\n", load_profile, ConfigError),
    "scene": ("name: s\nobjects: []\nobjects: []\n", load_scene, SceneError),
    "board": (BOARD.replace("squares_y: 6\n", "squares_y: 6\nsquares_x: 9\n"), load_board, BoardError),
    "calibration": ("mode: eye_to_hand\nmethod: x\nmethod: y\n", load_calibration, CalibrationError),
}


@pytest.mark.parametrize("kind", list(READERS))
def test_every_yaml_reader_refuses_a_repeated_key_naming_it(tmp_path, kind):
    text, reader, error = READERS[kind]
    path = tmp_path / f"{kind}.yaml"
    path.write_text(text)
    with pytest.raises(error, match=rf"{kind}\.yaml:\d+:\d+: \w+: duplicate key \(first set at line \d\)"):
        reader(path)


def test_repeated_nested_key_names_its_path_and_both_lines(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("safety:\n  padding_m: 0.05\n  workspace: {}\n  padding_m: 0.0\n")
    with pytest.raises(InputFileError) as e:
        load_yaml(path, "profile")
    assert (e.value.key, e.value.line) == ("safety.padding_m", 4) and "line 2" in e.value.problem


def test_yaml_merge_keys_are_not_duplicates(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("base: &b {x: 1, y: 2}\nchild:\n  <<: *b\n  x: 3\n")
    assert load_yaml(path, "profile")["child"] == {"x": 3, "y": 2}


def test_json_bounds_are_measured_before_parsing(tmp_path):
    path = tmp_path / "t.json"
    path.write_text('{"a": "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[["}')  # brackets in a string do not nest
    assert load_json(path, "t")["a"].startswith("[[")
    path.write_text("[" * 33 + "]" * 33)
    with pytest.raises(InputFileError, match="nested 33 levels"):
        load_json(path, "t")
    path.write_text("[" + "1," * 100 + "1]")
    with pytest.raises(InputFileError, match="values"):
        load_json(path, "t", max_values=50)


def test_npz_declared_sizes_are_checked_before_any_array_is_read(tmp_path, monkeypatch):
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        with zf.open("small.npy", "w") as f:
            np.lib.format.write_array(f, np.zeros(3))
        with zf.open("bomb.npy", "w") as f:
            np.lib.format.write_array_header_1_0(f, {"descr": "<f8", "fortran_order": False, "shape": (2**20, 2**10)})
    path = tmp_path / "a.npz"
    path.write_bytes(buf.getvalue())
    read = []
    monkeypatch.setattr(np.lib.format, "read_array", lambda *a, **k: read.append(a))
    with pytest.raises(InputFileError) as e:
        read_npz(path, "archive", 2**20, 2**20)
    assert e.value.key == "bomb" and "8,589,934,592 bytes" in e.value.problem and read == []
