"""The pools of worker processes (brdfcorr.tasks.pool): what a worker starts with, and its end."""

from __future__ import annotations

import multiprocessing
import os
import subprocess
import sys

import pytest

from brdfcorr.tasks import pool


def _environment_variable(name: str) -> str | None:
    return os.environ.get(name)


@pytest.mark.parametrize("start_methods", [None, ["spawn"]], ids=["forkserver", "spawn"])
def test_each_pool_gives_its_workers_the_environment_of_when_it_was_made(monkeypatch, start_methods):
    # The fork server keeps the environment it started with; each pool's workers take the caller's
    # as it is when the pool is made (a GDAL setting or credentials set between two runs). Spawned
    # workers, where there is no fork server to use, get it too.
    if start_methods is not None:
        monkeypatch.setattr(multiprocessing, "get_all_start_methods", lambda: start_methods)
    for value in ("first", "second"):
        monkeypatch.setenv("BRDFCORR_TEST_POOL_SETTING", value)
        with pool.worker_processes(1, ()) as executor:
            assert executor.submit(_environment_variable, "BRDFCORR_TEST_POOL_SETTING").result() == value
    monkeypatch.delenv("BRDFCORR_TEST_POOL_SETTING")
    with pool.worker_processes(1, ()) as executor:
        assert executor.submit(_environment_variable, "BRDFCORR_TEST_POOL_SETTING").result() is None


def test_a_process_that_has_ended_is_not_running_and_this_one_is():
    # The fallback watch of systems without pidfds (macOS) asks with signal 0.
    ended = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                           check=True)
    assert not pool._running(int(ended.stdout))
    assert pool._running(os.getpid())
