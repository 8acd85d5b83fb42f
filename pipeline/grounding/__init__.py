"""Spatial grounding: from the initial view and the goal view to the object's 3D motion (see ground.py)."""
