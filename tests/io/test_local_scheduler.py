"""The scheduler of a local pass, named by its function so that dask need not import dask.distributed
(brdfcorr.io.writer.local_scheduler)."""

from __future__ import annotations

import sys

import dask
import dask.local
import dask.threaded
import pytest

from brdfcorr.io.writer import local_scheduler


@pytest.fixture
def without_distributed(monkeypatch):
    """This process as one that has not imported dask.distributed."""
    for name in [name for name in sys.modules if name == "distributed" or name.startswith("distributed.")]:
        monkeypatch.delitem(sys.modules, name)


def test_names_and_none_become_dasks_own_functions(without_distributed):
    assert local_scheduler(None) is dask.threaded.get  # dask arrays' default
    assert local_scheduler("threads") is dask.threaded.get
    assert local_scheduler("Synchronous") is dask.local.get_sync
    with dask.config.set(scheduler="synchronous"):  # the user's dask setting stands
        assert local_scheduler(None) is dask.local.get_sync


def test_what_only_dask_can_resolve_is_left_to_it(without_distributed):
    client = object()
    assert local_scheduler(client) is client
    assert local_scheduler("distributed") == "distributed"  # dask: "no Client active"
    assert local_scheduler(dask.local.get_sync) is dask.local.get_sync


def test_with_distributed_imported_dask_looks_for_a_client_itself():
    import distributed  # noqa: F401

    assert local_scheduler(None) is None
    assert local_scheduler("threads") == "threads"
