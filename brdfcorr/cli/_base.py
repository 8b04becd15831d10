"""The ``brdfcorr`` command group, its error handling and the option parsers the commands share.

Commands parse arguments, call library functions, print tables and map errors to exit codes
(:data:`EXIT_CODES`): 2 for bad input or an output that cannot be written (any
:class:`brdfcorr.errors.BrdfcorrError`, and click's usage errors), 1 for internal failures (any
other exception), 3 when ``run`` finished but some scenes failed. An error is one line on stderr;
the global ``--debug`` option adds the traceback.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import importlib
import os
import select
import signal
import sys
import threading
import traceback
import warnings
from pathlib import Path

import click
import click.shell_completion

from brdfcorr import __version__
from brdfcorr._entry import entered
from brdfcorr.defaults import AUTO_MODEL, MODEL_NAMES, SURFACE_MODEL_NAMES, chunk_size_problem
from brdfcorr.errors import BrdfcorrError, BrdfcorrWarning, ParameterError
from brdfcorr.io.files import atomic_path, parse_yaml


class _ModelName(click.ParamType):
    """``--model``: a surface model of the registry (the registry's message for another name), from
    the names in :mod:`brdfcorr.defaults`: ``--help`` and a wrong name import no model (scipy)."""

    name = "model"

    def __init__(self, auto: bool = False):
        # A fit may also ask for the model with the lowest held-out error (brdfcorr.fit.selection).
        self.names = SURFACE_MODEL_NAMES + ((AUTO_MODEL,) if auto else ())

    def get_metavar(self, param, ctx=None) -> str:
        return "[" + "|".join(self.names) + "]"

    def shell_complete(self, ctx, param, incomplete):
        return [click.shell_completion.CompletionItem(n) for n in self.names if n.startswith(incomplete)]

    def convert(self, value, param, ctx):
        if value in self.names:
            return value
        if value not in MODEL_NAMES:  # get_model's message
            self.fail(f"unknown BRDF model {value!r}; known models: {', '.join(MODEL_NAMES)}", param, ctx)
        self.fail(f"{value!r} is not a surface model; surface models: {', '.join(SURFACE_MODEL_NAMES)}", param, ctx)


MODEL_CHOICE = _ModelName()
#: ``--model`` of the fits: a surface model or ``auto``.
FIT_MODEL_CHOICE = _ModelName(auto=True)


class _ChunkSize(click.ParamType):
    """``--chunk``: a chunk and tile size [pixels], a multiple of 16 in
    :data:`brdfcorr.defaults.CHUNK_RANGE` (the rule of a chain's ``engine.chunk``), refused while
    the options are parsed (0 divided by zero, a negative size failed inside dask)."""

    name = "integer"

    def convert(self, value, param, ctx):
        if isinstance(value, int) and not isinstance(value, bool):
            number = value
        else:
            try:
                number = int(str(value).strip(), 10)
            except ValueError:
                self.fail(f"{value!r} is not an integer", param, ctx)
        problem = chunk_size_problem(number)
        if problem:
            self.fail(f"{number} {problem}", param, ctx)
        return number


#: The type of every command's ``--chunk``.
CHUNK_SIZE = _ChunkSize()


#: ``--progress/--no-progress`` of the commands that read whole images (correct, fit-classes, assess,
#: classes ndvi): a bar on stderr, by default on a terminal only (:func:`progress_bars`).
PROGRESS = click.option("--progress/--no-progress", default=None, help="Progress bar [default: on a terminal].")


@contextlib.contextmanager
def progress_bars(progress: bool | None, description: str):
    """One progress bar on stderr over the tasks of every dask pass run in the block, from the first
    (the checks that read a few chunks) to the write, where ``progress`` (None: where stderr is a
    terminal): its total grows as each pass starts and its count only grows (tqdm's own dask
    callback started a new bar at every pass). Yields the callbacks entered (empty without a bar)."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        yield []
        return
    from tqdm import tqdm  # with dask: imported when a command runs, not for --help

    from brdfcorr.chain.progress import ChunkProgress

    bars: list = []

    def show(event: str, info: dict) -> None:
        if not bars:  # at the first pass's start, with its total
            bars.append(tqdm(desc=description, total=info["total"], unit="task", leave=False, file=sys.stderr))
        bar = bars[0]
        bar.total = info["total"]
        bar.update(info["done"] - bar.n)

    try:
        with ChunkProgress(description, show) as callback:
            yield [callback]
    finally:
        if bars:
            bars[0].close()


@contextlib.contextmanager
def class_bar(progress: bool | None, description: str, unit: str = "class"):
    """A counting bar on stderr (where ``progress``; None: where stderr is a terminal) of items
    that take seconds each (classes, fits); yields a callable ``update(item)`` that advances it
    (a no-op without a bar)."""
    if progress is None:
        progress = sys.stderr.isatty()
    if not progress:
        yield lambda item: None
        return
    from tqdm import tqdm

    # Every item shown (an item takes seconds; tqdm's rate limit would skip the last ones).
    with tqdm(desc=description, unit=unit, leave=False, file=sys.stderr, mininterval=0, miniters=1) as bar:
        yield lambda item: bar.update()


def _format_table(rows: list[dict[str, str]]) -> str:
    """Rows of equal keys as a plain aligned text table."""
    columns = list(rows[0])
    widths = {column: max(len(column), *(len(str(row[column])) for row in rows)) for column in columns}
    lines = ["  ".join(column.ljust(widths[column]) for column in columns)]
    lines.append("  ".join("-" * widths[column] for column in columns))
    lines += ["  ".join(str(row[column]).ljust(widths[column]) for column in columns) for row in rows]
    return "\n".join(lines)


#: Exit code of a bad input, config, parameter or option, or of an output that cannot be written.
EXIT_BAD_INPUT = 2
#: Exit code of an internal failure (a bug: any exception that is not a BrdfcorrError).
EXIT_INTERNAL = 1
#: Exit code of `brdfcorr run` when the run finished but some scenes failed (see the report).
EXIT_SCENES_FAILED = 3
#: Exit code after Ctrl-C (128 + SIGINT, as shells report it).
EXIT_INTERRUPTED = 130
#: Exit code after SIGTERM (128 + SIGTERM, as shells report it): stopped as after Ctrl-C.
EXIT_TERMINATED = 143
#: Exit code when the reader of the output went away (``brdfcorr models | head``): 128 + SIGPIPE, as
#: shells report a Unix tool that a closed pipe stopped.
EXIT_BROKEN_PIPE = 141
EXIT_CODES = {0: "success", EXIT_INTERNAL: "internal error (a bug; --debug shows the traceback)",
              EXIT_BAD_INPUT: "bad input, config, parameter or option, or an output that cannot be written",
              EXIT_SCENES_FAILED: "run: the run finished but some scenes failed (see the report)",
              EXIT_INTERRUPTED: "interrupted (Ctrl-C); partial outputs are removed",
              EXIT_TERMINATED: "terminated (SIGTERM); partial outputs and scratch folders are removed",
              EXIT_BROKEN_PIPE: "the reader of the output went away (a pipe closed early); stopped quietly"}


def _debug_enabled() -> bool:
    context = click.get_current_context(silent=True)
    return bool(context is not None and context.find_root().params.get("debug"))


def _fail(error: Exception):
    """One line on stderr (the traceback before it with --debug), then the exit code of the error."""
    if _debug_enabled():
        traceback.print_exception(error, file=sys.stderr)
    # One line: an unattended batch greps its logs line by line.
    text = " ".join(str(error).split("\n")).strip()
    if isinstance(error, BrdfcorrError):
        click.echo(f"brdfcorr: error: {text}", err=True)
        sys.exit(EXIT_BAD_INPUT)
    if isinstance(error, MemoryError):  # a resource limit (ulimit -v, a small machine), not a bug
        click.echo(f"brdfcorr: error: out of memory{': ' + text if text else ''}; a smaller tile size (--chunk) "
                   "or a higher memory limit (ulimit -v) helps", err=True)
        sys.exit(EXIT_BAD_INPUT)
    hint = "" if _debug_enabled() else " (rerun with --debug for the traceback)"
    click.echo(f"brdfcorr: internal error: {type(error).__name__}: {text}{hint}", err=True)
    sys.exit(EXIT_INTERNAL)


def _closed_streams() -> list:
    """stdout and stderr where their reader went away: a pipe whose read end is closed polls as
    an error (``POLLERR``), a closed socket as hung up."""
    closed = []
    for stream in (sys.stdout, sys.stderr):
        try:
            poller = select.poll()
            poller.register(stream.fileno(), 0)  # errors and hang-ups are always reported
            if any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0)):
                closed.append(stream)
        except (AttributeError, OSError, ValueError):  # no file descriptor (a test runner), no poll (Windows)
            continue
    return closed


def _stop_quietly(error: BrokenPipeError):
    """Exit quietly with :data:`EXIT_BROKEN_PIPE` when stdout or stderr lost its reader
    (``brdfcorr models | head``), as Unix tools stopped by SIGPIPE do: the closed streams are
    pointed at the null device, so that Python's final flush does not fail again (Python docs,
    ``signal``, "Note on SIGPIPE"). SIGPIPE itself stays ignored (Python's default), since its
    default action would also kill the process when a socket, e.g. to a dask scheduler, closes.
    Another broken pipe (not of our output) is a failure like any other (:func:`_fail`)."""
    closed = _closed_streams()
    if not closed:
        _fail(error)
    devnull = os.open(os.devnull, os.O_WRONLY)
    for stream in closed:
        os.dup2(devnull, stream.fileno())
    os.close(devnull)
    sys.exit(EXIT_BROKEN_PIPE)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread as Ctrl-C raises :class:`KeyboardInterrupt`, so that
    what is being written and the scratch folders of a command are removed on the way out (the
    default action of SIGTERM ends the process where it stands)."""


@contextlib.contextmanager
def terminate_as_interrupt():
    """While a command runs, SIGTERM raises :class:`Terminated` in the main thread; the previous
    handler is restored after. Outside the main thread (where no handler can be set) nothing
    changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminated(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)


def _free_half_built_objects(error: BaseException) -> None:
    """After a signal stopped a command: free the objects it interrupted in their ``__init__`` (the
    frames of ``error``'s traceback hold them) now, dropping what their ``__del__`` says (a file
    manager of xarray stopped half-built: "Exception ignored in ... has no attribute '_local'"), so
    that the command's one line is the last it prints. The previous hook is restored: an in-process
    caller (click's CliRunner, pytest) keeps its own."""
    previous, sys.unraisablehook = sys.unraisablehook, (lambda unraisable: None)
    try:
        traceback.clear_frames(error.__traceback__)
        gc.collect()
    finally:
        sys.unraisablehook = previous


def handle_errors(command):
    """Map exceptions to exit codes: :class:`BrdfcorrError` and click's usage errors -> one line
    and 2, any other exception -> one "internal error" line and 1; click's exit and abort pass."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            with entered("cli"):  # messages name the fixes as options (--wavelengths), brdfcorr._entry
                return command(*args, **kwargs)
        except click.UsageError as error:  # one line like every other error; the usage is in --help
            context = error.ctx or click.get_current_context(silent=True)  # raised in a command
            where = " ".join(context.command_path.split()[1:]) if context is not None else ""
            hint = f" (see --help of {where})" if where else ""
            click.echo(f"brdfcorr: error: {where + ': ' if where else ''}{error.format_message()}{hint}", err=True)
            sys.exit(error.exit_code)
        except Terminated as error:
            _free_half_built_objects(error)
            click.echo("brdfcorr: terminated", err=True)
            sys.exit(EXIT_TERMINATED)
        except (KeyboardInterrupt, click.exceptions.Abort) as error:
            # Ctrl-C: partial outputs are removed on the way out (atomic_path); 128 + SIGINT.
            _free_half_built_objects(error)
            click.echo("brdfcorr: interrupted", err=True)
            sys.exit(EXIT_INTERRUPTED)
        except (click.exceptions.ClickException, click.exceptions.Exit):
            raise
        except BrokenPipeError as error:
            _stop_quietly(error)
        except Exception as error:  # noqa: BLE001 (the one place every failure is turned into an exit code)
            _fail(error)

    return wrapper


#: Command -> (module defining it, its one-line help). A command's module is imported only when the
#: command runs, so `brdfcorr --help` and each command pay only for what they use (matplotlib,
#: scipy.optimize and rasterio load in seconds). tests/cli/test_cli_basic.py checks this table against
#: the commands themselves.
LAZY_COMMANDS: dict[str, tuple[str, str]] = {
    "analyze": (
        "brdfcorr.cli.analyze",
        "The papers' analyses: shadowing impact, azimuthal width, albedo, paper figures.",
    ),
    "assess": (
        "brdfcorr.cli.assess",
        "Did the BRDF correction work? View-angle slopes, side ratios, profiles and overlaps, before and after.",
    ),
    "assess-lines": (
        "brdfcorr.cli.assess",
        "Leave-one-line-out: fit on the other flight lines, correct and assess each held-out line.",
    ),
    "classes": (
        "brdfcorr.cli.classes",
        'Make class maps: NDVI strata of an image, or a land-cover map brought onto its grid.',
    ),
    "coefficients": (
        "brdfcorr.cli.info",
        "List the built-in BRDF coefficient sets, or show one set's weights per band.",
    ),
    "correct": (
        "brdfcorr.cli.correct",
        'Normalize IMAGE to a reference sun/view geometry with per-class BRDF models.',
    ),
    "demo": (
        "brdfcorr.cli.chain",
        'Build a demo airborne line, correct it with the demo chain and write a before/after picture.',
    ),
    "fit": (
        "brdfcorr.cli.fitting",
        'Fit a BRDF model to goniometer MEASUREMENTS (CSV: theta_i, theta_r, phi, brdf[, sigma, wavelength]).',
    ),
    "fit-classes": (
        "brdfcorr.cli.fitting",
        'Fit per-class, per-band BRDF parameters from IMAGES themselves (one or many scenes).',
    ),
    "materials": (
        "brdfcorr.cli.info",
        "List the built-in materials, or show one material's parameters with errors.",
    ),
    "models": (
        "brdfcorr.cli.info",
        'List the BRDF models and their parameters (units, defaults, physical range).',
    ),
    "nbar": (
        "brdfcorr.cli.nbar",
        "NBAR of a Sentinel-2 L2A SAFE or Landsat Collection-2 L2 folder with built-in coefficients.",
    ),
    "run": (
        "brdfcorr.cli.chain",
        'Run the processing chain CHAIN (YAML) over all its scenes and write a run report (JSON).',
    ),
    "validate": (
        "brdfcorr.cli.chain",
        'Check chain configs without running them: keys, values, names, patterns, parameter table.',
    ),
}


class _Group(click.Group):
    """The command group: every command and subgroup runs under :func:`handle_errors`; commands are
    loaded from :data:`LAZY_COMMANDS` when first used."""

    def list_commands(self, ctx):
        return sorted({*super().list_commands(ctx), *LAZY_COMMANDS})

    def get_command(self, ctx, name):
        if name not in self.commands and name in LAZY_COMMANDS:
            importlib.import_module(LAZY_COMMANDS[name][0])  # registers its commands on `main`
        return super().get_command(ctx, name)

    def _short_help(self, ctx, name: str) -> str:
        command = self.get_command(ctx, name)
        return command.get_short_help_str() if command is not None else ""

    def format_commands(self, ctx, formatter):
        # The listing from the table, without importing every command's module.
        rows = [(name, LAZY_COMMANDS[name][1] if name in LAZY_COMMANDS else self._short_help(ctx, name))
                for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def invoke(self, ctx):
        # Only brdfcorr's own warnings reach stderr (as "brdfcorr: warning:" lines where a command
        # shows them); third-party warnings (GDAL's NotGeoreferencedWarning, numpy's overflow
        # RuntimeWarnings, matplotlib) only with --debug.
        with warnings.catch_warnings():
            if not ctx.params.get("debug"):
                warnings.simplefilter("ignore")
                warnings.simplefilter("default", BrdfcorrWarning)
            warnings.showwarning = _warning_lines(warnings.showwarning)
            with terminate_as_interrupt():
                return handle_errors(super().invoke)(ctx)


def _warning_lines(fallback):
    """A ``warnings.showwarning`` that writes brdfcorr's own warnings as one ``brdfcorr: warning:
    ...`` line each (from any command, a chain's scenes included) and passes the others (shown
    with --debug) to ``fallback``."""

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, BrdfcorrWarning):
            click.echo(f"brdfcorr: warning: {message}", err=True)
        else:
            fallback(message, category, filename, lineno, file, line)

    return show


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]},
             epilog="Exit codes: 0 success; 2 bad input, config, parameter or option, or an output "
                    "that cannot be written (one line on stderr naming the file, key, band or class); "
                    "1 internal error (a bug; --debug shows the traceback); 3 run: some scenes failed; "
                    "130 interrupted; 143 terminated.")
@click.option("--debug", is_flag=True, help="Show the traceback of an error, and third-party warnings.")
@click.version_option(__version__, prog_name="brdfcorr")
def main(debug):
    """Specular BRDF models and BRDF normalization of reflectance imagery."""


class Assignment(click.ParamType):
    """``NAME=VALUE`` (or ``NAME=LOW:HIGH`` with ``ranges``) with numbers, converted to the pair
    ``(name, value)`` or ``(name, (low, high))``; a repeatable option collects the pairs (``dict``
    of them), and with :func:`distinct_names` as its callback a name given twice with different
    values is refused. A bad item is click's usage error (exit 2)."""

    pairs = True  # converts to (name, value): a repeated name is checked (:func:`distinct_names`)

    def __init__(self, ranges: bool = False):
        self.ranges = ranges
        self.name = "NAME=LOW:HIGH" if ranges else "NAME=VALUE"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):  # converted already (a default)
            return value
        name, _, text = str(value).partition("=")
        try:
            number = tuple(float(part) for part in text.split(":")) if self.ranges else float(text)
            if self.ranges and len(number) != 2:
                raise ValueError
        except ValueError:
            self.fail(f"{value!r}: expected {self.name} with numbers", param, ctx)
        return name.strip(), number


def distinct_names(ctx, param, pairs):
    """Callback of a repeatable option of ``(name, value)`` pairs (a type with ``pairs = True``:
    :class:`Assignment`, :class:`ReaderOption`, :class:`ClassPair`): the pairs as given, refused
    (click's usage error, exit 2) where a name comes twice with different values (``--fix k=0.25
    --fix k=0.3``, ``--class-model 2=rpv --class-model 2=ross_li_ts``: which one was meant? a
    ``dict`` of them kept the last without a word)."""
    first: dict = {}
    for name, value in pairs or ():
        if first.setdefault(name, value) != value:
            raise click.BadParameter(f"{name} is given twice, as {name}={_assigned(first[name])} and "
                                     f"{name}={_assigned(value)}: give it once", ctx, param)
    return pairs


def _assigned(value) -> str:
    """The value of a pair as it is written: ``0.25``, ``0:1``, ``rpv``."""
    if isinstance(value, tuple):
        return ":".join(f"{part:g}" for part in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


class ReaderOption(click.ParamType):
    """``KEY=VALUE`` of a reader (``--angle-option``), converted to ``(key, value)`` with the value
    read as a YAML scalar (``20`` -> 20, ``B04`` -> "B04"; text that is no YAML scalar stays text)."""

    name = "KEY=VALUE"
    pairs = True

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        key, separator, text = str(value).partition("=")
        if not separator or not key.strip():
            self.fail(f"{value!r}: expected KEY=VALUE", param, ctx)
        try:
            scalar = parse_yaml(text, "--angle-option", ParameterError) if text.strip() else ""
        except ParameterError:  # not a YAML scalar: the text itself
            scalar = text
        return key.strip(), scalar


class ClassPair(click.ParamType):
    """``ID=TEXT``: a class id (a non-negative integer) and a text (a name, a model), converted to
    ``(id, text)``; a repeatable option collects the pairs (``dict`` of them)."""

    pairs = True

    def __init__(self, what: str = "NAME"):
        self.name = f"ID={what}"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        key, _, text = str(value).partition("=")
        if not key.strip().isdigit() or not text.strip():
            self.fail(f"{value!r}: expected CLASS_ID=VALUE, e.g. 2=grass", param, ctx)
        return int(key), text.strip()


#: The types of the KEY=VALUE and ID=NAME options (repeatable; ``dict(value)`` collects them).
NAME_VALUE = Assignment()
NAME_RANGE = Assignment(ranges=True)
READER_OPTION = ReaderOption()
CLASS_NAME = ClassPair("NAME")
CLASS_MODEL = ClassPair("MODEL")


def _draw_figure(figure, path: Path, target: Path, *, dpi: int = 110) -> None:
    """Draw ``figure`` into ``path`` (a temporary file of a joint write,
    :func:`brdfcorr.io.files.atomic_paths`) in the format of ``target``'s suffix (png without one)."""
    figure.savefig(path, dpi=dpi, format=target.suffix.lstrip(".") or "png")


def _save_figure(figure, target: Path, *, dpi: int = 110, echo: bool = True) -> None:
    target.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(target) as temporary:
        _draw_figure(figure, temporary, target, dpi=dpi)
    if echo:
        click.echo(f"wrote {target}")

