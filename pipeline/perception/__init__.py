"""Perception backends: segmenters, depth estimators and dense features (each imports its heavy library lazily)."""
