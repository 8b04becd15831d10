"""One rule for the dask threads of a scene when the user names none: a chain's ``threads`` engine
uses as many as ``brdfcorr correct`` (one per :data:`brdfcorr.defaults.CORES_PER_THREAD` cores),
not one per core."""

from __future__ import annotations

import os

import pytest

from brdfcorr import defaults
from brdfcorr.chain.config import load_config
from brdfcorr.chain.config_outputs import EngineConfig
from brdfcorr.chain.run import _executor
from brdfcorr.io import writer


@pytest.fixture
def cores(monkeypatch):
    """``cores(n)``: this machine has, and this process may use, ``n`` cores."""
    def set_cores(count: int) -> None:
        monkeypatch.setattr(os, "cpu_count", lambda: count)
        monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(count)), raising=False)
    return set_cores


def _chain_threads(engine: EngineConfig) -> int | None:
    with _executor(engine) as (executor, compute):
        assert executor is None
        return compute["threads"]


@pytest.mark.parametrize("count", [1, 2, 3, 4, 8, 16, 64])
def test_a_threads_chain_uses_the_threads_of_correct(cores, count):
    cores(count)
    correct_threads = writer.pass_threads(None, None)  # `brdfcorr correct`: no thread count, dask's default scheduler
    assert correct_threads == defaults.default_threads() == max(1, count // defaults.CORES_PER_THREAD)
    assert _chain_threads(EngineConfig(scheduler="threads")) == correct_threads


def test_a_chain_file_without_workers_follows_the_rule(cores, tmp_path, make_scenes, write_chain):
    cores(16)
    make_scenes(tmp_path)
    config = load_config(write_chain(tmp_path, engine={"scheduler": "threads"}))
    assert _chain_threads(config.engine) == 4


def test_given_workers_are_the_threads(cores):
    cores(16)
    assert _chain_threads(EngineConfig(scheduler="threads", workers=16)) == 16
    assert _chain_threads(EngineConfig(scheduler="threads", workers=1)) == 1
