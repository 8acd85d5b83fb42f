"""Evaluation campaigns: many whole runs over task scenes, seeds and trials, on worker processes or Ray."""
