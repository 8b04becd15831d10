"""A pool of worker processes for the independent fits of a task (the candidates' folds of
``fit --model auto``, the classes of ``fit-classes --workers``), as a ``with`` block."""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import warnings
from collections.abc import Iterator

from brdfcorr.errors import BrdfcorrWarning

__all__ = ["process_pool"]


@contextlib.contextmanager
def process_pool(workers: int) -> Iterator[concurrent.futures.Executor | None]:
    """A pool of ``workers`` fresh processes (spawned: no thread of this one is copied; each imports
    what its tasks need, about a second) for the ``with`` block; None for one worker (the caller
    then works in this process), and where no process pool can be made here (no semaphores: a
    system without ``/dev/shm``), which a :class:`~brdfcorr.errors.BrdfcorrWarning` says. Leaving
    the block early (an error, Ctrl-C) cancels the tasks not started, so it waits for the running
    ones only."""
    if workers <= 1:
        yield None
        return
    try:
        pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))
    except (OSError, NotImplementedError, ImportError) as error:
        warnings.warn(f"no worker processes can be started here ({error}); the fits run in this process",
                      BrdfcorrWarning, stacklevel=3)
        yield None
        return
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
