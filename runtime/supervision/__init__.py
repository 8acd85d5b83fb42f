"""Supervision and stopping: the state machine, the supervisor, e-stops and their latch, the confirm gate, status."""
