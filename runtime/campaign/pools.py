"""Where a campaign's cases run: processes on this machine, or a Ray cluster. Both take the same work
(runtime.campaign.worker.execute_case with plain arguments) and hand back concurrent.futures.Future objects, so the
campaign waits on, gathers and resumes both the same way.
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Protocol

from runtime.campaign.worker import execute_case


class Pool(Protocol):
    description: str

    def submit(self, *args: object) -> Future: ...

    def close(self, cancel: bool = False) -> None: ...


class ProcessPool:
    """`workers` processes on this machine, each started fresh (spawn: no forked threads or GL contexts) and kept
    for its later cases."""

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise ValueError(f"--workers must be at least 1, got {workers}")
        self.description = f"{workers} worker process{'es' if workers > 1 else ''} on this machine"
        self._executor = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"))

    def submit(self, *args: object) -> Future:
        return self._executor.submit(execute_case, *args)

    def close(self, cancel: bool = False) -> None:
        self._executor.shutdown(wait=not cancel, cancel_futures=cancel)


class RayPool:
    """Ray tasks of one CPU each: on the cluster at `address`, or `local` for a Ray instance started here with
    `workers` CPUs. Every node must have the project installed (setup.sh) with the same profile paths."""

    def __init__(self, address: str, workers: int) -> None:
        import ray

        options = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
        if address == "local":
            ray.init(num_cpus=workers, **options)
            self.description = f"a local Ray instance with {workers} CPUs"
        else:
            ray.init(address=address, **options)
            self.description = f"the Ray cluster at {address}"
        self._ray = ray
        # a run is not retried by Ray: a crashed case has no result.json and runs again when the campaign resumes
        self._remote = ray.remote(num_cpus=1, max_retries=0)(execute_case)

    def submit(self, *args: object) -> Future:
        return self._remote.remote(*args).future()

    def close(self, cancel: bool = False) -> None:
        self._ray.shutdown()
