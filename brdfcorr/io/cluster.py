"""Connecting to a dask.distributed cluster, bounded end to end: the address, the handshake, the workers.

:class:`distributed.Client`'s own ``timeout`` bounds the TCP connect, not the handshake that
follows: at a port where something listens but does not speak dask's protocol (an HTTP server, a
silent TCP server) the client waits forever, and a scheduler without workers makes every
computation wait forever. :func:`connect_cluster` therefore

1. parses the address and asks the scheduler for its identity (dask's ``identity`` operation of
   :mod:`distributed.comm`), in a thread of its own that is given up after a bounded time, so no
   client exists until a scheduler has answered (a client that fails half-made is what printed
   ``Client.__del__`` tracebacks at exit);
2. makes the :class:`distributed.Client` and waits a bounded time for at least one worker
   (:meth:`distributed.Client.wait_for_workers`), closing the client when none comes;
3. while the client is held, watches the workers (:class:`_WorkerWatch`): a scheduler whose last
   worker dies keeps the run's tasks waiting for a new one forever, so once it has had none for
   the same bounded time the run's computations are cancelled and the run stops with one line.

Each failure is one :class:`~brdfcorr.errors.InputError` naming the setting the address came from
(``--scheduler``, ``engine.address``). dask.distributed is an optional dependency, imported here
only when a cluster is asked for.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import threading
import time
from collections.abc import Iterator
from typing import Any

from brdfcorr.errors import InputError

__all__ = ["CONNECT_TIMEOUT", "WORKER_TIMEOUT", "connect_cluster", "scheduler_identity"]

#: Seconds to reach a scheduler and hear its identity (connect and handshake together).
CONNECT_TIMEOUT = 10.0
#: Seconds to wait for the first worker of a scheduler that has none yet.
WORKER_TIMEOUT = 60.0
#: Seconds the probe thread is given beyond its own timeout before it is abandoned.
_MARGIN = 2.0
#: Seconds between two looks at the workers of a cluster a run holds.
_WATCH_INTERVAL = 0.5


def _distributed(setting: str) -> Any:
    try:  # an optional dependency, for clusters only
        import distributed
    except ImportError:
        raise InputError(f"{setting}: a dask.distributed cluster needs the dask.distributed package "
                         "(pip install 'dask[distributed]')") from None
    return distributed


async def _identity(address: str, timeout: float) -> Any:
    """The scheduler's reply to dask's ``identity`` operation (connect, handshake, one request)."""
    from distributed.comm import connect
    from distributed.security import Security

    comm = await connect(address, timeout=timeout, **Security().get_connection_args("client"))
    try:
        await comm.write({"op": "identity", "reply": True})
        return await comm.read()
    finally:
        comm.abort()


def scheduler_identity(address: str, timeout: float, setting: str = "scheduler address") -> dict:
    """What the dask scheduler at ``address`` says it is, heard within about ``timeout`` seconds.

    Parameters
    ----------
    address : str
        ``tcp://host:port`` (any address :mod:`distributed.comm` takes).
    timeout : float
        Seconds for the connect, the handshake and the reply together [s].
    setting : str
        Where the address came from, for messages (``--scheduler``, ``engine.address``).

    Returns
    -------
    dict
        The scheduler's identity (``type`` ``"Scheduler"``, ``id``, ``workers``, ...).

    Raises
    ------
    InputError
        An address that is none, nothing answering, or an answer that is not a scheduler's.
    """
    outcome: dict[str, Any] = {}

    def probe() -> None:
        try:
            outcome["reply"] = asyncio.run(asyncio.wait_for(_identity(address, timeout), timeout))
        except BaseException as error:  # noqa: BLE001 - handed to the caller's thread below
            outcome["error"] = error

    # A thread of its own (and its own event loop): abandoned if it does not end in time, and
    # usable where the caller already runs an event loop (a notebook).
    thread = threading.Thread(target=probe, name="brdfcorr-scheduler-probe", daemon=True)
    thread.start()
    thread.join(timeout + _MARGIN)
    error = outcome.get("error")
    unreachable = f"{setting}: cannot reach the dask scheduler at {address}"
    if isinstance(error, ValueError):  # the address does not parse
        raise InputError(f"{setting}: {address!r} is no dask scheduler address ({error}); "
                         "expected e.g. tcp://host:8786") from None
    if thread.is_alive() or isinstance(error, (TimeoutError, asyncio.TimeoutError)):
        raise InputError(f"{unreachable}: no answer within {timeout:g} s (is something other than a "
                         "dask scheduler listening there?)")
    if isinstance(error, OSError):
        raise InputError(f"{unreachable}: {error}") from None
    reply = outcome.get("reply")
    if error is not None or not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise InputError(f"{unreachable}: something answers there, but not as a dask scheduler")
    return reply


@contextlib.contextmanager
def connect_cluster(address: str | None = None, *, workers: int = 1, threads_per_worker: int = 1,
                    setting: str | None = None, timeout: float | None = None,
                    worker_timeout: float | None = None) -> Iterator[Any]:
    """A :class:`distributed.Client` of the dask scheduler at ``address`` with at least one worker,
    or of a local cluster of ``workers`` processes with ``threads_per_worker`` threads each made
    here; the client (and a local cluster) is closed on exit.

    The client is not made dask's default: pass it as the ``scheduler`` of a computation.

    Parameters
    ----------
    address : str, optional
        The scheduler's address (``tcp://host:8786``); None makes a local cluster.
    workers, threads_per_worker : int
        Size of a local cluster (``address`` None).
    setting : str, optional
        Where the address came from, for messages (``--scheduler``, ``engine.address``).
    timeout : float, optional
        Seconds to reach the scheduler and hear its identity (default :data:`CONNECT_TIMEOUT`).
    worker_timeout : float, optional
        Seconds to wait for a first worker (default :data:`WORKER_TIMEOUT`).

    Raises
    ------
    InputError
        dask.distributed is not installed; the address is none; nothing answers as a dask
        scheduler within ``timeout``; no worker joins within ``worker_timeout``.
    """
    where = setting or "scheduler address"
    distributed = _distributed(where)
    timeout = CONNECT_TIMEOUT if timeout is None else float(timeout)
    worker_timeout = WORKER_TIMEOUT if worker_timeout is None else float(worker_timeout)
    with contextlib.ExitStack() as stack:
        if address is None:
            cluster = stack.enter_context(distributed.LocalCluster(
                n_workers=workers, threads_per_worker=threads_per_worker, processes=True, dashboard_address=None))
            address = cluster.scheduler_address
        scheduler_identity(address, timeout, where)
        try:
            client = distributed.Client(address, set_as_default=False, timeout=timeout)
        except (OSError, TimeoutError) as error:
            raise InputError(f"{where}: cannot reach the dask scheduler at {address}: {error}") from None
        stack.callback(client.close)
        try:
            client.wait_for_workers(1, timeout=worker_timeout)
        except TimeoutError:
            raise InputError(f"{where}: the dask scheduler at {address} has no workers (none joined within "
                             f"{worker_timeout:g} s); start workers with dask-worker {address}") from None
        watch = stack.enter_context(_WorkerWatch(client, worker_timeout, (
            f"{where}: the dask scheduler at {address} lost its last worker and none joined within "
            f"{worker_timeout:g} s; the run was stopped (restart workers and run again)")))
        try:
            yield client
        except concurrent.futures.CancelledError:
            if watch.fired:
                raise InputError(watch.message) from None
            raise


class _WorkerWatch:
    """A context that cancels every computation of ``client`` once its scheduler has had no worker
    for ``timeout`` seconds.

    dask moves a lost worker's tasks to the others, but a scheduler left without any keeps them
    waiting for a new worker forever (``distributed.scheduler.no-workers-timeout`` is off by
    default, and it is the scheduler's own setting, not the client's). A daemon thread looks at the
    workers every :data:`_WATCH_INTERVAL` seconds; where the time runs out it cancels the client's
    futures, so the waiting computation raises :class:`concurrent.futures.CancelledError` (with
    ``message``) and :attr:`fired` is set. A worker that joins in time resets the clock.
    """

    def __init__(self, client: Any, timeout: float, message: str) -> None:
        self.client, self.timeout, self.message = client, timeout, message
        self.fired = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="brdfcorr-worker-watch", daemon=True)

    def __enter__(self) -> _WorkerWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stop.set()
        self._thread.join()

    def _watch(self) -> None:
        without_since = None
        while not self._stop.wait(_WATCH_INTERVAL):
            try:
                workers = self.client.scheduler_info(n_workers=1).get("workers")
            except Exception:  # noqa: BLE001 - the scheduler itself is gone: the client's own error says so
                return
            now = time.monotonic()
            if workers:
                without_since = None
            elif without_since is None:
                without_since = now
            elif now - without_since > self.timeout and self.client.futures:
                self._cancel()
                without_since = None

    def _cancel(self) -> None:
        from distributed import Future

        self.fired = True
        pending = [Future(key, self.client) for key in list(self.client.futures)]
        self.client.cancel(pending, force=True, reason="no worker", msg=self.message)
