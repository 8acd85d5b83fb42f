"""Pick an off-screen OpenGL backend for MuJoCo before it is imported, or say exactly what is missing.

MuJoCo reads MUJOCO_GL once, at import. On a headless machine the default (GLFW) cannot open a context, so we
probe EGL (GPU or Mesa) and then OSMesa in a child process and export the first that renders. Everything in the
project imports mujoco through this module.
"""

from __future__ import annotations

import os
import subprocess
import sys

_PROBE = (
    "import mujoco\n"
    "m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size=\"1\"/></worldbody></mujoco>')\n"
    "r = mujoco.Renderer(m, 8, 8); r.update_scene(mujoco.MjData(m)); r.render(); r.close()\n"
)
MISSING_HINT = (
    "no off-screen OpenGL backend works for MuJoCo. Install one: "
    "`apt-get install libegl1 libgl1-mesa-dri` (EGL) or `apt-get install libosmesa6` (OSMesa), "
    "or set MUJOCO_GL to a backend that works on this machine."
)


class RenderBackendError(RuntimeError):
    pass


def _works(backend: str) -> bool:
    env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=60)
    except subprocess.TimeoutExpired:
        return False
    return done.returncode == 0


def select_backend() -> str:
    """The MUJOCO_GL value to use: the user's choice if set, else the first of egl, osmesa that renders."""
    chosen = os.environ.get("MUJOCO_GL")
    if chosen:
        return chosen
    for backend in ("egl", "osmesa"):
        if _works(backend):
            return backend
    raise RenderBackendError(MISSING_HINT)


if "mujoco" not in sys.modules:
    _backend = select_backend()
    os.environ["MUJOCO_GL"] = _backend
    os.environ.setdefault("PYOPENGL_PLATFORM", _backend)

import mujoco  # noqa: E402  (must follow the backend selection)


def release_context() -> None:
    """Unbind the EGL context from the calling thread. EGL lets a context be current on one thread at a time and
    mujoco.Renderer binds it at creation, so a process that renders on a worker thread releases it here first."""
    if os.environ.get("MUJOCO_GL") != "egl":
        return
    import mujoco.egl as mj_egl

    if mj_egl.EGL_DISPLAY is not None:
        egl = mj_egl.EGL
        egl.eglMakeCurrent(mj_egl.EGL_DISPLAY, egl.EGL_NO_SURFACE, egl.EGL_NO_SURFACE, egl.EGL_NO_CONTEXT)


__all__ = ["RenderBackendError", "mujoco", "release_context", "select_backend"]
