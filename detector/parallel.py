"""A process pool that is only started when there is more than one worker."""
from __future__ import annotations

import multiprocessing as mp
import os
import signal
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
    pool = mp.get_context("spawn" if os.name == "nt" else "fork").Pool(workers, initializer=_plain_signals)
    try:
        yield from pool.imap(function, items, chunksize=chunksize)
    finally:
        pool.terminate()


def _plain_signals() -> None:
    """A worker dies at once on SIGTERM and leaves Ctrl-C to its parent.

    A forked worker would otherwise inherit the command's SIGTERM handler (which raises to clean up), and the
    ``terminate()`` that ends every pool could then interrupt a worker while it holds the task queue's lock, leaving
    the other workers waiting on that lock forever.
    """
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def default_workers(jobs: int) -> int:
    """Every core, but no more processes than jobs."""
    return max(1, min(os.cpu_count() or 1, jobs))
