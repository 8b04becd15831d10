"""Commands in processes of their own, forked from a server that has imported the package.

A fresh interpreter spends about 2 s importing numpy, xarray, dask, rasterio and matplotlib before
it reads its first argument. ``multiprocessing``'s fork server imports them once per test worker
(:func:`_server`) and forks a child per command, which starts in milliseconds and is still a process
of its own: its own exit code, file descriptors, resource limits and signals, and a hang guard that
kills it. Tests of what a fresh interpreter imports (tests/cli/test_cli_startup.py) start one.
"""

from __future__ import annotations

import concurrent.futures
import functools
import importlib.metadata
import multiprocessing
import os
import pkgutil
import resource
import runpy
import signal
import subprocess
import sys
from pathlib import Path

import brdfcorr


@functools.cache
def _server() -> multiprocessing.context.BaseContext:
    """The fork server, which imports every module of the package (3.5 s, once), pyplot and this
    module before it forks: a command then imports nothing more (``validate``: 25 ms, not 2 s)."""
    modules = [module.name for module in pkgutil.walk_packages(brdfcorr.__path__, "brdfcorr.")
               if not module.name.endswith(".__main__")]
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([*modules, "matplotlib.pyplot", __name__])
    return context


def _child(argv: list[str], cwd: str | None, environment: dict[str, str], outputs: tuple, file_size_limit: int | None
           ) -> None:
    """In the forked child: the caller's directory and environment, stdout and stderr into the
    pipes ``outputs``, then ``argv`` run as its console script (``brdfcorr``) or as ``python
    script.py`` would run it; the child's exit code is the command's."""
    if cwd is not None:
        os.chdir(cwd)
    os.environ.clear()
    os.environ.update(environment)
    for descriptor, pipe in zip((1, 2), outputs):
        os.dup2(pipe.fileno(), descriptor)
        pipe.close()
    if file_size_limit is not None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (file_size_limit, file_size_limit))
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
    if argv[0] == "brdfcorr":
        (script,) = importlib.metadata.entry_points(group="console_scripts", name="brdfcorr")
        script.load()(argv[1:], prog_name="brdfcorr")
    elif argv[0] == "python" and len(argv) > 1:
        sys.argv, sys.path[0] = argv[1:], str(Path(argv[1]).resolve().parent)
        runpy.run_path(argv[1], run_name="__main__")
    else:
        raise ValueError(f"not a brdfcorr or python script command: {argv}")


def _drained(pipe) -> str:
    """Everything written into ``pipe`` until its last writer closes it, as text."""
    chunks = []
    while chunk := os.read(pipe.fileno(), 1 << 16):
        chunks.append(chunk)
    pipe.close()
    return b"".join(chunks).decode(errors="replace")


def run(argv: list, *, cwd: Path | str | None = None, env: dict[str, str] | None = None, timeout: float = 300,
        file_size_limit: int | None = None) -> subprocess.CompletedProcess:
    """Run ``brdfcorr ARGS...`` or ``python SCRIPT ARGS...`` in a forked process of its own, in
    ``cwd``, with the environment ``env`` (default: this process's), under a file size limit
    [bytes] if given (stdout and stderr are pipes, as ``subprocess.run`` makes them: not held to
    it); killed after ``timeout`` [s] (:class:`subprocess.TimeoutExpired`, as ``subprocess.run``
    raises). Returns what ``subprocess.run`` returns: the exit code, stdout and stderr as text."""
    argv = [str(word) for word in argv]
    server = _server()
    pipes = [server.Pipe(duplex=False) for _ in range(2)]
    environment = dict(os.environ if env is None else env)
    child = server.Process(target=_child, args=(argv, None if cwd is None else str(cwd), environment,
                                                tuple(writer for _, writer in pipes), file_size_limit))
    child.start()
    for _, writer in pipes:
        writer.close()
    with concurrent.futures.ThreadPoolExecutor(2) as readers:
        outputs = [readers.submit(_drained, reader) for reader, _ in pipes]
        child.join(timeout)
        if child.exitcode is None:
            child.kill()
            child.join()
            raise subprocess.TimeoutExpired(argv, timeout)
        stdout, stderr = (output.result() for output in outputs)
    return subprocess.CompletedProcess(argv, child.exitcode, stdout, stderr)
