"""Output cut by a closed pipe (``brdfcorr models | head``): a quiet stop with exit 141 (128 + SIGPIPE,
as shells report a Unix tool stopped by the pipe), no traceback and no "internal error" line
(issue 28; Python docs, ``signal``, "Note on SIGPIPE")."""

from __future__ import annotations

import subprocess
import sys

import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.cli._base import EXIT_BROKEN_PIPE, EXIT_INTERNAL

_CLI = "from brdfcorr.cli import main; main()"


@pytest.mark.parametrize("command", [["models"], ["materials"]])
def test_a_reader_that_goes_away_stops_the_command_quietly(command):
    # A real pipe whose reader closes before the command writes its first line: every write fails
    # with EPIPE (Python ignores SIGPIPE, so the process sees BrokenPipeError).
    process = subprocess.Popen([sys.executable, "-c", _CLI, *command], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    process.stdout.close()
    stderr = process.stderr.read().decode()
    process.stderr.close()
    assert process.wait(timeout=60) == EXIT_BROKEN_PIPE == 141
    assert stderr == ""  # no traceback, no "internal error", no "Exception ignored" at the final flush


def test_a_broken_pipe_elsewhere_is_still_an_error(monkeypatch):
    # A BrokenPipeError that is not about our own output (here stdout is the runner's buffer) is
    # not swallowed: it stays an internal error with its one line.
    import brdfcorr.cli.info

    def broken(*args, **kwargs):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(brdfcorr.cli.info, "material_names", broken)
    result = CliRunner().invoke(main, ["materials"])
    assert result.exit_code == EXIT_INTERNAL
    assert result.stderr.startswith("brdfcorr: internal error: BrokenPipeError")
