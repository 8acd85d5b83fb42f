"""Manipulation: a contact decision turned into gate-approved phases (approach, grasp, carry, push, home)."""
