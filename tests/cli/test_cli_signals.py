"""Ctrl-C and third-party warnings at the command line: exit 130 with one line, partial outputs
removed; only brdfcorr's own warnings on stderr unless --debug."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import _forked
from click.testing import CliRunner

from brdfcorr.cli import EXIT_INTERRUPTED, main

_WARNS = """
import warnings, click
from brdfcorr.cli import main
from brdfcorr.errors import BrdfcorrWarning

@main.command("warns")
def warns():
    warnings.warn("a third-party warning", RuntimeWarning, stacklevel=1)
    warnings.warn("a brdfcorr warning", BrdfcorrWarning, stacklevel=1)
    click.echo("done")

main()
"""


def _stderr(*args: str) -> str:
    result = subprocess.run([sys.executable, "-c", _WARNS, *args], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stderr


def test_third_party_warnings_only_with_debug():
    # A real process: pytest records warnings itself, so the CLI's filtering shows only outside it.
    stderr = _stderr("warns")
    assert "a third-party warning" not in stderr and "a brdfcorr warning" in stderr
    assert "a third-party warning" in _stderr("--debug", "warns")
    # brdfcorr's own warning is one line of ours, whatever the command: no Python format, no source line.
    assert stderr.splitlines() == ["brdfcorr: warning: a brdfcorr warning"]


def test_keyboard_interrupt_is_exit_130_with_one_line(monkeypatch):
    import brdfcorr.cli.info

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(brdfcorr.cli.info, "material_names", interrupted)
    result = CliRunner().invoke(main, ["materials"])
    assert result.exit_code == EXIT_INTERRUPTED == 130
    assert result.stderr.splitlines() == ["brdfcorr: interrupted"]


def test_sigint_during_a_write_exits_130_and_leaves_no_partial_file(tmp_path):
    # A real SIGINT to a real process (forked from one that has imported the package:
    # tests/_forked.py), in the middle of writing the demo scene's outputs.
    output = tmp_path / "demo"
    process = _forked.start(["brdfcorr", "demo", "-o", output, "--no-progress"])
    for _ in range(30_000):  # a hang guard of at most 300 s of polling, not a measurement
        if any(output.rglob("*.partial")) or process.poll() is not None:
            break
        time.sleep(0.01)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    if process.returncode == 0:  # finished before the signal arrived: nothing to check
        return
    assert process.returncode == 130, stderr
    assert stderr.splitlines()[-1] == "brdfcorr: interrupted"
    assert not [path for path in output.rglob("*") if path.name.endswith(".partial")]
    assert os.path.isdir(output)


def test_readme_lists_the_interrupt_exit_code():
    assert "| 130 | interrupted" in (Path(__file__).parents[2] / "README.md").read_text()


def test_running_out_of_memory_is_one_line_and_exit_2(monkeypatch):
    """A MemoryError (``ulimit -v`` 400 MB) was an internal error, exit 1 (issue 39): it is a
    resource limit, named as one."""
    import brdfcorr.cli.info

    def exhausted(*args, **kwargs):
        raise MemoryError("Unable to allocate 1.31 TiB for an array")

    monkeypatch.setattr(brdfcorr.cli.info, "material_names", exhausted)
    result = CliRunner().invoke(main, ["materials"])
    assert result.exit_code == 2
    assert result.stderr.splitlines() == ["brdfcorr: error: out of memory: Unable to allocate 1.31 TiB for an array; "
                                          "a smaller tile size (--chunk) or a higher memory limit (ulimit -v) helps"]
