import pytest

from drivers.sim import gl


def test_user_choice_is_respected(monkeypatch):
    monkeypatch.setenv("MUJOCO_GL", "osmesa")
    assert gl.select_backend() == "osmesa"


def test_first_working_backend_is_chosen(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "_works", lambda backend: backend == "osmesa")
    assert gl.select_backend() == "osmesa"


def test_missing_backends_name_the_packages(monkeypatch):
    monkeypatch.delenv("MUJOCO_GL", raising=False)
    monkeypatch.setattr(gl, "_works", lambda backend: False)
    with pytest.raises(gl.RenderBackendError, match=r"libegl1 libgl1-mesa-dri.*libosmesa6"):
        gl.select_backend()


def test_probe_really_renders_with_the_selected_backend():
    assert gl._works(gl.select_backend())
