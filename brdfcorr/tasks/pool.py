"""Pools of worker processes for the independent work of a task (the candidates' folds of ``fit
--model auto``, the classes of ``fit-classes --workers``, the scenes of a chain's ``processes``
engine).

Workers are forked from :mod:`multiprocessing`'s fork server where the system has one (Linux and
the other POSIX systems but macOS): it imports the modules the work needs once, and each worker is
a fork of it that starts in milliseconds instead of importing them again (up to a second and a half
a worker). The server is a fresh process of its own, so, as with spawned workers, no thread or lock
of the calling process is copied mid-use. On macOS, whose system libraries may start threads in the
server as it imports (Python spawns there by default for that reason), and on Windows, the workers
are spawned.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import os
import select
import signal
import sys
import threading
import time
import warnings
from collections.abc import Iterator, Mapping, Sequence

from brdfcorr.errors import BrdfcorrWarning

__all__ = ["process_pool", "worker_processes"]


def worker_processes(workers: int, modules: Sequence[str]) -> concurrent.futures.ProcessPoolExecutor:
    """A process pool of ``workers`` workers for work from ``modules``.

    Parameters
    ----------
    workers : int
        Number of worker processes.
    modules : sequence of str
        Modules the workers' tasks need, imported once by the fork server where it starts with this
        pool. The server lives as long as this process and keeps the modules it started with; a
        later pool's workers import what else they need themselves.

    Returns
    -------
    concurrent.futures.ProcessPoolExecutor
        Each worker starts with this process's environment variables as they are now (the fork
        server's are those of when it started), its working directory and ``sys.path``, and (POSIX)
        ends when this process ends, however it ends (kill -9 included), instead of working on for a
        caller that is gone (:func:`_end_with`).
    """
    if sys.platform != "darwin" and "forkserver" in multiprocessing.get_all_start_methods():
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(list(modules))  # no effect once this process's server runs
    else:
        context = multiprocessing.get_context("spawn")
    return concurrent.futures.ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker,
                                                  initargs=(dict(os.environ), os.getpid()))


def _start_worker(environment: Mapping[str, str], caller: int) -> None:
    """In a new worker: the environment variables of the pool's maker, and a watch on its process
    (POSIX only: on Windows ``os.kill(pid, 0)`` would end the process it asks about)."""
    os.environ.clear()
    os.environ.update(environment)
    if os.name == "posix":
        threading.Thread(target=_end_with, args=(caller,), name="brdfcorr-caller-watch", daemon=True).start()


def _end_with(caller: int) -> None:
    """Wait for the process ``caller`` to end, then end this one (SIGTERM). The worker's parent may
    be the fork server, which outlives the caller while its workers live, so the wait is on the
    caller itself: a pidfd on Linux, else a look once a second."""
    try:
        descriptor = os.pidfd_open(caller)
    except (AttributeError, OSError):  # no pidfd here, or the caller has already ended
        while _running(caller):
            time.sleep(1.0)
    else:  # readable once the process has ended (poll: no limit on the descriptor's number)
        watch = select.poll()
        watch.register(descriptor, select.POLLIN)
        watch.poll()
    os.kill(os.getpid(), signal.SIGTERM)


def _running(pid: int) -> bool:
    """Whether the process ``pid`` is there (signal 0 checks without sending anything)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # there, but another user's
        pass
    return True


@contextlib.contextmanager
def process_pool(workers: int, modules: Sequence[str]) -> Iterator[concurrent.futures.Executor | None]:
    """A pool of ``workers`` processes for work from ``modules`` (:func:`worker_processes`) for the
    ``with`` block; None for one worker (the caller then works in this process), and where no
    process pool can be made here (no semaphores: a system without ``/dev/shm``), which a
    :class:`~brdfcorr.errors.BrdfcorrWarning` says. Leaving the block early (an error, Ctrl-C)
    cancels the tasks not started, so it waits for the running ones only."""
    if workers <= 1:
        yield None
        return
    try:
        pool = worker_processes(workers, modules)
    except (OSError, NotImplementedError, ImportError) as error:
        warnings.warn(f"no worker processes can be started here ({error}); the fits run in this process",
                      BrdfcorrWarning, stacklevel=3)
        yield None
        return
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
