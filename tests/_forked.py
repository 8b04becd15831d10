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
import multiprocessing.forkserver
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
    module before it forks: a command then imports nothing more (``validate``: 25 ms, not 2 s).

    Started at once (tests/conftest.py does so as the session starts): the library's worker pools
    (brdfcorr.tasks.pool) fork from this process's one fork server too, and one started first by a
    pool would have the pool's few modules only."""
    modules = [module.name for module in pkgutil.walk_packages(brdfcorr.__path__, "brdfcorr.")
               if not module.name.endswith(".__main__")]
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload([*modules, "matplotlib.pyplot", __name__])
    multiprocessing.forkserver.ensure_running()
    return context


def _child(argv: list[str], cwd: str | None, environment: dict[str, str], outputs: tuple, file_size_limit: int | None
           ) -> None:
    """In the forked child: the caller's directory and environment, stdout and stderr into the
    pipes ``outputs``, then ``argv`` run as its console script (``brdfcorr``) or as ``python
    script.py`` would run it; the child's exit code is the command's."""
    signal.signal(signal.SIGINT, signal.default_int_handler)  # Ctrl-C as in a fresh interpreter
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


class Child:
    """A command started by :func:`start`, as ``subprocess.Popen`` has it: ``pid``, ``poll()``,
    ``send_signal()``, ``kill()``, ``wait()`` and ``communicate()`` (stdout and stderr as text);
    ``returncode`` is ``-N`` for a child ended by signal N."""

    def __init__(self, argv: list[str], process, readers: concurrent.futures.ThreadPoolExecutor, outputs: list):
        self.args, self._process, self._readers, self._outputs = argv, process, readers, outputs

    @property
    def pid(self) -> int:
        return self._process.pid

    @property
    def returncode(self) -> int | None:
        return self._process.exitcode

    def poll(self) -> int | None:
        return self._process.exitcode

    def send_signal(self, number: int) -> None:
        os.kill(self.pid, number)

    def kill(self) -> None:
        self._process.kill()

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        if self._process.exitcode is None:
            raise subprocess.TimeoutExpired(self.args, timeout)
        return self._process.exitcode

    def communicate(self, timeout: float | None = None) -> tuple[str, str]:
        self.wait(timeout)
        stdout, stderr = (output.result() for output in self._outputs)
        self._readers.shutdown()
        return stdout, stderr


def start(argv: list, *, cwd: Path | str | None = None, env: dict[str, str] | None = None,
          file_size_limit: int | None = None) -> Child:
    """Start ``brdfcorr ARGS...`` or ``python SCRIPT ARGS...`` (as :func:`run`) and return at once:
    the running :class:`Child`, whose stdout and stderr are read meanwhile."""
    argv = [str(word) for word in argv]
    server = _server()
    pipes = [server.Pipe(duplex=False) for _ in range(2)]
    environment = dict(os.environ if env is None else env)
    child = server.Process(target=_child, args=(argv, None if cwd is None else str(cwd), environment,
                                                tuple(writer for _, writer in pipes), file_size_limit))
    child.start()
    for _, writer in pipes:
        writer.close()
    readers = concurrent.futures.ThreadPoolExecutor(2)
    return Child(argv, child, readers, [readers.submit(_drained, reader) for reader, _ in pipes])


def run(argv: list, *, cwd: Path | str | None = None, env: dict[str, str] | None = None, timeout: float = 300,
        file_size_limit: int | None = None) -> subprocess.CompletedProcess:
    """Run ``brdfcorr ARGS...`` or ``python SCRIPT ARGS...`` in a forked process of its own, in
    ``cwd``, with the environment ``env`` (default: this process's), under a file size limit
    [bytes] if given (stdout and stderr are pipes, as ``subprocess.run`` makes them: not held to
    it); killed after ``timeout`` [s] (:class:`subprocess.TimeoutExpired`, as ``subprocess.run``
    raises). Returns what ``subprocess.run`` returns: the exit code, stdout and stderr as text."""
    child = start(argv, cwd=cwd, env=env, file_size_limit=file_size_limit)
    try:
        stdout, stderr = child.communicate(timeout)
    except subprocess.TimeoutExpired:
        child.kill()
        child.communicate()
        raise
    return subprocess.CompletedProcess(child.args, child.returncode, stdout, stderr)
