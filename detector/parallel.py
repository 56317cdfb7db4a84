"""A process pool that is only started when there is more than one worker."""
from __future__ import annotations

import gc
import multiprocessing as mp
import multiprocessing.pool
import os
import signal
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar
from naoslam.cores import usable_cores

T = TypeVar("T")
R = TypeVar("R")


def ordered_map(function: Callable[[T], R], items: Iterable[T], workers: int, chunksize: int = 4) -> Iterator[R]:
    """``map(function, items)`` in order, spread over ``workers`` processes (in this process when workers <= 1).

    ``function`` must be a module-level function; results must not depend on which process ran them.
    """
    if workers <= 1:
        yield from map(function, items)
        return
    pool = _pool(workers)
    try:
        yield from pool.imap(function, items, chunksize=chunksize)
    finally:
        pool.terminate()


#: Signals a forked worker holds from its birth until ``_plain_signals`` has set how it takes them.
_WORKER_SIGNALS = {signal.SIGTERM, signal.SIGINT}


def _pool(workers: int) -> mp.pool.Pool:
    """Worker processes, forked where the system can.

    A forked worker must never run the destructor of an onnxruntime session: it waits for the session's thread-pool
    threads, which were not forked, forever. A session the parent left in a reference cycle is freed by whichever
    process's garbage collector runs next, so the parent collects its garbage first and its workers inherit the rest
    frozen (``gc.freeze``: outside every collection they make).
    """
    if os.name == "nt":
        return mp.get_context("spawn").Pool(workers, initializer=_plain_signals)
    gc.collect()
    gc.freeze()
    held = signal.pthread_sigmask(signal.SIG_BLOCK, _WORKER_SIGNALS)  # forked workers start with these held
    try:
        return mp.get_context("fork").Pool(workers, initializer=_plain_signals)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, held)
        gc.unfreeze()


def _plain_signals() -> None:
    """A worker dies at once on SIGTERM and leaves Ctrl-C to its parent.

    A forked worker would otherwise inherit the command's SIGTERM handler (which raises to clean up), and the
    ``terminate()`` that ends every pool could then interrupt a worker while it holds the task queue's lock, leaving
    the other workers waiting on that lock forever. A SIGTERM that comes before this runs (``terminate()`` while a
    worker has not yet been scheduled after its fork) is held until the handler is the default one: taken by the
    inherited handler before ``multiprocessing``'s bootstrap, it would raise in the child, which then ran on as a copy
    of its parent (seen once as a test run that hung).
    """
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if os.name != "nt":
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _WORKER_SIGNALS)


def default_workers(jobs: int) -> int:
    """Every core, but no more processes than jobs."""
    return max(1, min(usable_cores(), jobs))
