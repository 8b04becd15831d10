"""The dask scheduler of a pass, resolved without importing dask.distributed where it cannot be used."""

from __future__ import annotations

import sys

import dask
import dask.base
import dask.threaded

__all__ = ["local_scheduler"]


def local_scheduler(scheduler):
    """``scheduler`` as :func:`dask.compute` takes it, a name or None resolved to a local
    scheduler's function where no dask.distributed Client can exist (distributed not imported).

    dask looks for a current Client on every pass with a name or None as the scheduler, and so
    imports dask.distributed (0.3 s, a third of a small correction) where it is installed; a
    function is taken as given. None is dask's ``scheduler`` setting, else the threaded scheduler
    of dask arrays. With distributed imported (a Client may be current), and for a Client,
    ``"distributed"`` or another object, ``scheduler`` is returned unchanged for dask to resolve.
    """
    if "distributed" in sys.modules or not (scheduler is None or isinstance(scheduler, str)):
        return scheduler
    name = scheduler if scheduler is not None else dask.config.get("scheduler", None)
    if name is None:
        return dask.threaded.get
    if not isinstance(name, str):
        return name
    return dask.base.named_schedulers.get(name.lower(), name)
