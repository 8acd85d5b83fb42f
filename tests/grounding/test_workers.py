"""Grounding's threads keep the native libraries' pools to one thread each, and give them back after."""

from __future__ import annotations

import threading

import pytest
import torch  # noqa: F401  loads the OpenMP runtime that Open3D's ICP and torch share
from threadpoolctl import threadpool_info

from pipeline.grounding.workers import one_thread_each, workers


def _threads(api: str) -> int:
    """The calling thread's thread count of the first loaded pool of that API."""
    return next(d["num_threads"] for d in threadpool_info() if d["user_api"] == api)


def _in_plain_thread(api: str) -> int:
    out: list[int] = []
    t = threading.Thread(target=lambda: out.append(_threads(api)))
    t.start()
    t.join()
    return out[0]


def test_a_workers_openmp_is_one_thread_where_a_plain_thread_would_have_more() -> None:
    plain = _in_plain_thread("openmp")
    if plain == 1:
        pytest.skip("this machine's OpenMP default is one thread: nothing to keep down")
    with workers() as pool:
        counts = list(pool.map(lambda _: _threads("openmp"), range(4)))
    assert counts == [1, 1, 1, 1]


def test_one_thread_each_limits_blas_while_grounding_and_restores_it() -> None:
    before = _threads("blas")
    with one_thread_each():
        assert _threads("blas") == 1
        assert _threads("openmp") == 1
    assert _threads("blas") == before
