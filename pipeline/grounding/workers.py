"""Threads for grounding's steps that do not depend on each other, and the native thread pools kept out of their way.

ICP, tree searches, torch and numpy's larger operations leave the interpreter free, so two steps run side by side on
two cores. The native libraries' own pools would then oversubscribe the cores: Open3D's ICP on every core inside
each of two workers, OpenBLAS's threads on small matrices beside them. So grounding keeps each library to one
thread while it runs (one_thread_each) and each worker keeps OpenMP to one thread of its own (a new thread's OpenMP
count starts from the process default, whatever its caller set). Same answers; a raycast pair about 390 -> 280 ms on a
2-core machine (bench/grounding.py)."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from contextlib import AbstractContextManager
from functools import cache

from threadpoolctl import ThreadpoolController

SIDE_BY_SIDE = 2  # grounding's parallel work is two-way: features beside geometry, ICP beside ICP


@cache
def _controller() -> ThreadpoolController:
    """The native thread pools loaded (found once: a search of the loaded libraries costs over a millisecond)."""
    return ThreadpoolController()


def one_thread_each() -> AbstractContextManager:
    """Context manager: every native pool (OpenMP for the calling thread, BLAS for the process) at one thread. BLAS's
    count is the process's: two ground() calls overlapping in threads may leave it at one (slower, never wrong); the
    runtime grounds on one stage thread and campaigns in processes."""
    return _controller().limit(limits=1)


def _one_openmp_thread() -> None:
    _controller().limit(limits=1, user_api="openmp")


def workers(count: int = SIDE_BY_SIDE) -> ThreadPoolExecutor:
    """A pool of `count` threads, each keeping OpenMP to one thread; use it as a context manager."""
    return ThreadPoolExecutor(max_workers=count, initializer=_one_openmp_thread)
