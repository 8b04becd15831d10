"""A pool of worker processes for the independent fits of a task (the candidates' folds of
``fit --model auto``, the classes of ``fit-classes --workers``), as a ``with`` block."""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
from collections.abc import Iterator

__all__ = ["process_pool"]


@contextlib.contextmanager
def process_pool(workers: int) -> Iterator[concurrent.futures.Executor | None]:
    """A pool of ``workers`` fresh processes (spawned: no thread of this one is copied; each imports
    what its tasks need, about a second) for the ``with`` block; None for one worker (the caller
    then works in this process). Leaving the block early (an error, Ctrl-C) cancels the tasks not
    started, so it waits for the running ones only."""
    if workers <= 1:
        yield None
        return
    pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
