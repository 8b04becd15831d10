"""Small file helpers: outputs appear complete or not at all; YAML is parsed safely."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

import yaml


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike):
    """Yield a temporary path beside ``target``; rename it onto ``target`` only on success.

    A crash or an exception inside the block leaves no file at ``target`` (and removes the
    temporary one), so a partial output never looks complete.
    """
    target = Path(target)
    handle, temporary = tempfile.mkstemp(
        prefix=f".{target.name}.", suffix=".partial", dir=target.parent or "."
    )
    os.close(handle)
    # mkstemp creates the file private (0600); give the output the mode a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(temporary, 0o666 & ~umask)
    try:
        yield Path(temporary)
        os.replace(temporary, target)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(temporary)


def parse_yaml(text: str, source: str, error: type[Exception]) -> object:
    """Parse YAML text with ``yaml.safe_load`` (plain data only: no Python objects, no code).

    Every problem becomes one ``error`` (a :class:`~brdfcorr.errors.BrdfcorrError` subclass) whose
    message names ``source`` and, for syntax errors, the line and column.
    """
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as problem:
        mark = getattr(problem, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        reason = getattr(problem, "problem", None) or " ".join(str(problem).split())
        raise error(f"{source}: not valid YAML{where}: {reason}") from None
    except (ValueError, TypeError, RecursionError) as problem:
        # PyYAML's constructors raise these for a timestamp that is no date (2001-02-30), a
        # mapping key that cannot be hashed, or a nesting too deep to build.
        raise error(f"{source}: not valid YAML: {' '.join(str(problem).split())}") from None
