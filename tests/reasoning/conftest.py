"""Fixtures of the reasoning tests (the fake provider server lives in fake_http.py)."""

from fake_http import fake_server, scene_rgb

__all__ = ["fake_server", "scene_rgb"]
