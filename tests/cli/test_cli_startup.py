"""The command line starts without the heavy libraries (issue 15: ``--help`` and argument errors
answer in <= 0.5 s).

A property, not a timing: importing a command's module, showing ``brdfcorr --help``, or refusing
an unknown option loads none of xarray, numpy, dask, scipy, rasterio, pandas or matplotlib; the
library is imported in the command's body, when it runs. ``import brdfcorr`` registers the
``.brdf`` accessor without importing xarray (``brdfcorr._accessor_hook``). Each check runs in a
fresh interpreter, since this test session has long imported everything.
"""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from brdfcorr.cli._base import LAZY_COMMANDS

#: The libraries whose import costs the command line its start (each 0.05-1 s on 2 cores).
HEAVY = ("xarray", "numpy", "dask", "scipy", "rasterio", "pandas", "matplotlib")

#: Command modules that still import the library at module level (none: every one is checked).
NOT_YET_LAZY: set[str] = set()

COMMAND_MODULES = sorted({module for module, _ in LAZY_COMMANDS.values()} - NOT_YET_LAZY)

#: Print the heavy libraries loaded so far (the last line of the subprocess's output).
_REPORT = f"import sys; print(sorted(m for m in {HEAVY!r} if m in sys.modules))"


def _heavy_after(code: str) -> list[str]:
    """The heavy libraries in sys.modules of a fresh interpreter after running ``code``."""
    result = subprocess.run([sys.executable, "-c", f"{code}\n{_REPORT}"], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stderr
    return ast.literal_eval(result.stdout.strip().splitlines()[-1])


def _main_with(*args: str) -> str:
    """Code that runs the click group with ``args`` as ``brdfcorr`` would, catching its exit."""
    return f"from brdfcorr.cli import main\ntry:\n    main({list(args)!r})\nexcept SystemExit:\n    pass"


def test_the_command_line_itself_loads_no_heavy_library():
    assert _heavy_after("import brdfcorr.cli") == []


def test_not_yet_lazy_names_command_modules():
    # A stale entry (a renamed or removed module) would silently exempt nothing.
    assert NOT_YET_LAZY <= {module for module, _ in LAZY_COMMANDS.values()}


@pytest.mark.parametrize("module", COMMAND_MODULES)
def test_importing_a_command_module_loads_no_heavy_library(module):
    assert _heavy_after(f"import brdfcorr.cli; import {module}") == []


def test_help_loads_no_heavy_library():
    assert _heavy_after(_main_with("--help")) == []


def _command_paths() -> list[tuple[str, ...]]:
    """Every command as typed: each of :data:`LAZY_COMMANDS`, and each subcommand of a group."""
    import click

    from brdfcorr.cli import main

    context = click.Context(main)
    paths: list[tuple[str, ...]] = []
    for name in sorted(LAZY_COMMANDS):
        command = main.get_command(context, name)
        paths.append((name,))
        if isinstance(command, click.Group):
            paths += [(name, sub) for sub in command.list_commands(context)]
    return paths


@pytest.mark.parametrize("command", _command_paths(), ids=" ".join)
def test_every_commands_help_loads_no_heavy_library(command):
    # `brdfcorr fit --help` once imported the model registry (scipy) to list the --model choices.
    assert _heavy_after(_main_with(*command, "--help")) == []


def test_a_wrong_model_name_is_refused_without_a_heavy_library():
    assert _heavy_after(_main_with("fit", "--model", "bogus")) == []


@pytest.mark.parametrize("command", [name for name, (module, _) in LAZY_COMMANDS.items()
                                     if module not in NOT_YET_LAZY])
def test_an_unknown_option_is_refused_without_a_heavy_library(command):
    # `brdfcorr COMMAND --bogus`: click refuses the option before the command's body runs. A group
    # (`classes`, `analyze`) refuses it before choosing a subcommand.
    assert _heavy_after(_main_with(command, "--bogus")) == []


def test_python_dash_m_brdfcorr_is_the_command():
    # Where the console script is not on the PATH: the same group, its name and its exit codes.
    version = subprocess.run([sys.executable, "-m", "brdfcorr", "--version"], capture_output=True, text=True,
                             timeout=120)
    assert version.returncode == 0 and version.stdout.startswith("brdfcorr, version ")
    refused = subprocess.run([sys.executable, "-m", "brdfcorr", "materials", "asphalt"], capture_output=True,
                             text=True, timeout=120)
    assert refused.returncode == 2 and refused.stderr.startswith("brdfcorr: error: unknown material 'asphalt'")
