"""The ``brdfcorr`` command line: a thin layer over the library.

Commands parse arguments, call library functions, print tables and map errors to exit codes
(:data:`EXIT_CODES`): 2 for bad input or an output that cannot be written (any
:class:`brdfcorr.errors.BrdfcorrError`, and click's usage errors), 1 for internal failures (any
other exception), 3 when ``run`` finished but some scenes failed, 130 when interrupted, 143 when
terminated (SIGTERM: removed what it was writing, as after Ctrl-C), 141 when
the reader of the output went away (``brdfcorr models | head``). An error is one line on stderr;
the global ``--debug`` option adds the traceback. One module per group of commands; a command's
module is imported when the command is first used (:data:`~brdfcorr.cli._base.LAZY_COMMANDS`),
which registers it on :data:`main`.
"""

from brdfcorr.cli._base import (
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_CODES,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_SCENES_FAILED,
    EXIT_TERMINATED,
    handle_errors,
    main,
)

__all__ = [
    "main", "handle_errors", "EXIT_CODES", "EXIT_BAD_INPUT", "EXIT_INTERNAL", "EXIT_SCENES_FAILED", "EXIT_INTERRUPTED",
    "EXIT_BROKEN_PIPE", "EXIT_TERMINATED",
]
