"""The simulator's ground truth, for benches and tests only: never used to decide a run."""
