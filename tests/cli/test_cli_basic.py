"""The foundation CLI commands: models, materials (the demo: tests/workflow/test_demo.py)."""

from click.testing import CliRunner

from brdfcorr.cli import main


def test_models_lists_every_parameter_with_units():
    result = CliRunner().invoke(main, ["models"])
    assert result.exit_code == 0, result.output
    assert "torrance_sparrow" in result.output and "deg^-1" in result.output
    assert "empirical" in result.output and "rad^-4" in result.output


def test_materials_table_and_unknown_material():
    runner = CliRunner()
    result = runner.invoke(main, ["materials", "roof_tile"])
    assert result.exit_code == 0
    assert "0.0362 ± 0.0004" in result.output and "4.1" in result.output
    result = runner.invoke(main, ["materials", "asphalt"])
    assert result.exit_code == 2
    assert "unknown material 'asphalt'" in result.output
    assert "Traceback" not in result.output


def test_atomic_path_leaves_nothing_on_failure_and_uses_the_default_mode(tmp_path):
    import os

    import pytest

    from brdfcorr.io.files import atomic_path

    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as temporary:
            temporary.write_text("partial")
            raise RuntimeError("killed mid-write")
    assert list(tmp_path.iterdir()) == []
    with atomic_path(target) as temporary:
        temporary.write_text("complete")
    umask = os.umask(0)
    os.umask(umask)
    assert target.read_text() == "complete"
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask


def test_lazy_command_table_matches_the_commands():
    # `brdfcorr --help` lists commands from LAZY_COMMANDS without importing them: the table must
    # name the module that defines each command and its own one-line help.
    import importlib

    import click

    from brdfcorr.cli._base import LAZY_COMMANDS

    context = click.Context(main)
    for name, (module, short_help) in LAZY_COMMANDS.items():
        importlib.import_module(module)
        command = main.commands[name]
        assert command.callback.__module__ == module, name
        assert short_help == command.get_short_help_str(limit=300), name
    assert sorted(main.list_commands(context)) == sorted(LAZY_COMMANDS)


def test_help_does_not_import_the_commands():
    import subprocess
    import sys

    code = ("import sys; from brdfcorr.cli import main\n"
            "try:\n    main(['--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.startswith(('matplotlib', 'rasterio', 'scipy.optimize', 'pvlib'))))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip().splitlines()[-1] == "[]", result.stdout


def test_help_texts_have_no_doubled_percent():
    # click does not %-format help strings: "%%" would be shown as it is ("5-95 %% view zenith").
    import click

    def commands(group, path):
        context = click.Context(group)
        for name in group.list_commands(context):
            command = group.get_command(context, name)
            yield (*path, name), command
            if isinstance(command, click.Group):
                yield from commands(command, (*path, name))

    runner = CliRunner()
    for path, command in commands(main, ()):
        texts = [command.help or ""] + [getattr(p, "help", None) or "" for p in command.params]
        assert not [text for text in texts if "%%" in text], path
        result = runner.invoke(main, [*path, "--help"])
        assert result.exit_code == 0 and "%%" not in result.output, (path, result.output)
    result = runner.invoke(main, ["fit-classes", "--help"])
    assert "5-95 % view zenith spread" in " ".join(result.output.split())


def test_a_signal_mid_construction_leaves_the_one_line_last():
    """SIGTERM can arrive inside an object's ``__init__`` (xarray's file manager, CI of stop 44);
    its ``__del__`` then failed at shutdown and printed a traceback after "brdfcorr: terminated".
    The hook that drops it is the caller's again afterwards (an in-process caller keeps its own)."""
    import subprocess
    import sys

    script = """
import sys
from brdfcorr.cli._base import Terminated, handle_errors

class HalfBuilt:
    def __init__(self):
        self.cycle = self
        raise Terminated
    def __del__(self):
        self._local.close()

@handle_errors
def command():
    HalfBuilt()

try:
    command()
except SystemExit as stop:
    print(sys.unraisablehook is sys.__unraisablehook__)
    raise
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 143
    assert done.stderr.splitlines() == ["brdfcorr: terminated"]
    assert done.stdout.strip() == "True"
