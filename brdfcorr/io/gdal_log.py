"""GDAL's log, as rasterio passes it on, while brdfcorr reads or writes files: one handler
(:class:`GdalLog`) collects it for one clear error instead of log lines on stderr.

Reading (:mod:`brdfcorr.io.opening`, :mod:`brdfcorr.io.rasters`): the messages of a failed read,
or GDAL's warnings about a header. Writing (:mod:`brdfcorr.io.writer`, :mod:`brdfcorr.io.commit`):
GDAL reports a tile it could not write, or a TIFF directory it could not rewrite at close, as a
logged error and rasterio raises nothing for it (a full disk gave files that read as NaN, with
exit 0), so those failures are collected and the write fails if there is one.
"""

from __future__ import annotations

import ctypes
import functools
import logging
import threading

__all__ = ["GdalLog", "OUT_OF_MEMORY"]

#: The start of the cause of a failed allocation (:meth:`GdalLog.cause`).
OUT_OF_MEMORY = "GDAL could not allocate memory"
_CPLE_OUT_OF_MEMORY = 2  # GDAL's error number of a failed allocation


class GdalLog(logging.Handler):
    """GDAL's log while files are read or written (a context manager).

    ``GdalLog(level, thread)`` while reading: :attr:`messages`, the text of rasterio's records at
    ``level`` or above (``logging.WARNING``: also GDAL's warnings, such as a header tag it could not
    read). ``GdalLog(thread=..., failures=True)`` while outputs are written and closed:
    :attr:`failures`, GDAL's failures (``CE_Failure``: a tile or line that was not written, a
    directory that could not be rewritten), which rasterio logs at INFO level and raises nothing
    for a failed flush or close; the loggers' level is lowered while any such write is active, the
    caller's handlers get what they got before, and libtiff's own printing of its errors is switched
    off (:func:`_quiet_libtiff`): nothing reaches stderr.

    Parameters
    ----------
    level : int, default logging.ERROR
        The least level of the messages collected (reading).
    thread : int, optional
        Only the records of this thread (a cluster's workers write; scenes run side by side here).
    failures : bool, default False
        Collect GDAL's failures while writing instead of messages.
    """

    _active = 0
    _saved: dict[str, tuple[int, bool, int]] = {}  # name: (level, propagate, effective level before)
    _guard = threading.Lock()
    _NAMES = ("rasterio._env", "rasterio._err")

    def __init__(self, level: int = logging.ERROR, thread: int | None = None, *, failures: bool = False):
        super().__init__(logging.INFO if failures else level)
        self.messages: list[str] = []
        self.failures: list[tuple[int, str]] = []
        self.thread = thread
        self.watch_failures = failures

    def emit(self, record: logging.LogRecord) -> None:
        if self.thread is not None and record.thread != self.thread:
            return
        if not self.watch_failures:
            self.messages.append(record.getMessage().strip())
            return
        args = record.args if isinstance(record.args, tuple) else ()
        if record.levelno >= logging.INFO and "err_no" in str(record.msg) and len(args) == 2:
            failure = (int(args[0]), str(args[1]).strip())
            if failure not in self.failures:
                self.failures.append(failure)

    def __enter__(self):
        if not self.watch_failures:
            logging.getLogger("rasterio").addHandler(self)
            return self
        _quiet_libtiff()
        with self._guard:
            if GdalLog._active == 0:
                for name in self._NAMES:
                    logger = logging.getLogger(name)
                    GdalLog._saved[name] = (logger.level, logger.propagate, logger.getEffectiveLevel())
                    # INFO records reach the handlers here; the caller's handlers get what they got before.
                    logger.setLevel(logging.INFO)
                    logger.propagate = False
                    logger.addHandler(_forward)
            GdalLog._active += 1
            for name in self._NAMES:
                logging.getLogger(name).addHandler(self)
        return self

    def __exit__(self, *exc):
        if not self.watch_failures:
            logging.getLogger("rasterio").removeHandler(self)
            return False
        with self._guard:
            for name in self._NAMES:
                logging.getLogger(name).removeHandler(self)
            GdalLog._active -= 1
            if GdalLog._active == 0:
                for name, (level, propagate, _) in GdalLog._saved.items():
                    logger = logging.getLogger(name)
                    logger.removeHandler(_forward)
                    logger.setLevel(level)
                    logger.propagate = propagate
        return False

    def cause(self) -> str:
        """GDAL's last failure in words ("" if none)."""
        if not self.failures:
            return ""
        number, message = self.failures[-1]
        return f"{OUT_OF_MEMORY}: {message}" if number == _CPLE_OUT_OF_MEMORY else f"GDAL: {message}"


class _Forward(logging.Handler):
    """While :class:`GdalLog` (``failures=True``) lowers the level of rasterio's error loggers, passes on to their
    parents the records the caller's logging would have had (at or above the level before)."""

    def emit(self, record: logging.LogRecord) -> None:
        level, propagate, effective = GdalLog._saved.get(record.name, (0, True, logging.NOTSET))
        if propagate and record.levelno >= effective:
            logger = logging.getLogger(record.name).parent
            if logger is not None:
                logger.handle(record)


_forward = _Forward()


@functools.cache
def _quiet_libtiff() -> None:
    """Switch off libtiff's printing of errors and warnings to stderr (its default handlers).

    GDAL reads libtiff's messages through per-file handlers and passes them on as GDAL errors
    (collected by :class:`GdalLog`); a few, such as ``_tiffWriteProc: No space left on
    device``, go only to libtiff's process-wide handlers, which print them. The libtiff that GDAL
    uses is the one mapped into this process (Linux: ``/proc/self/maps``); elsewhere nothing changes.
    """
    try:
        with open("/proc/self/maps") as maps:
            found = {line.split()[-1] for line in maps if "/libtiff" in line and ".so" in line}
        for path in found:
            library = ctypes.CDLL(path)
            for name in ("TIFFSetErrorHandler", "TIFFSetWarningHandler"):
                function = getattr(library, name)
                function.restype, function.argtypes = ctypes.c_void_p, [ctypes.c_void_p]
                function(None)
    except (OSError, AttributeError):  # no /proc, or a libtiff without these functions
        pass
