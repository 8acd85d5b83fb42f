"""Optional packages: the model backends' and the hardware SDKs' (torch/transformers, google-genai, openai, xarm,
pyorbbecsdk), imported only by the backend that needs them. A profile that names such a backend is checked for
its packages at start-up, so a missing one is a clear error there, before anything moves."""

from __future__ import annotations

import importlib.util


def missing_package(module: str, distribution: str, needed_by: str) -> str | None:
    """A readable problem when `module` cannot be imported (found without importing it: some are slow or print),
    naming what needs it and the distribution to install; None when it is there."""
    try:
        found = importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a parent package missing, or a broken one
        found = False
    if found:
        return None
    return f"{needed_by} needs the package {distribution} (import {module}), which is not installed"
