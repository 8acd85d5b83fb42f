"""Messaging: the Zenoh bus, its message schemas and the operator console that speaks them."""
