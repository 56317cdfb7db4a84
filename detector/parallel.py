"""A process pool that is only started when there is more than one worker."""
from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")


def ordered_map(function: Callable[[T], R], items: Iterable[T], workers: int, chunksize: int = 4) -> Iterator[R]:
    """``map(function, items)`` in order, spread over ``workers`` processes (in this process when workers <= 1).

    ``function`` must be a module-level function; results must not depend on which process ran them.
    """
    if workers <= 1:
        yield from map(function, items)
        return
    pool = mp.get_context("spawn" if os.name == "nt" else "fork").Pool(workers)
    try:
        yield from pool.imap(function, items, chunksize=chunksize)
    finally:
        pool.terminate()


def default_workers(jobs: int) -> int:
    """Every core, but no more processes than jobs."""
    return max(1, min(os.cpu_count() or 1, jobs))
