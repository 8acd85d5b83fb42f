"""The run and its stages: the run loop, what it hands its stages, the stages themselves and the run record."""
