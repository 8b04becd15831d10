"""The brdfcorr exception hierarchy.

Every error brdfcorr raises on purpose derives from :class:`BrdfcorrError`, so a caller (the CLI,
a batch chain) can tell "the input is wrong" from "the program is wrong" (the CLI exits with 2
for a BrdfcorrError and 1 for anything else). The narrow classes also
derive from the builtin they refine (``ValueError``), so plain ``except ValueError`` keeps working.
"""

from __future__ import annotations


class BrdfcorrError(Exception):
    """Root of all errors raised deliberately by brdfcorr."""


class ParameterError(BrdfcorrError, ValueError):
    """A model parameter is unknown, missing, NaN or outside its physical range."""


class UnknownNameError(BrdfcorrError, KeyError):
    """A model or material name is not in the registry or the material library."""

    def __str__(self) -> str:  # KeyError would repr() the message and add quotes
        return str(self.args[0]) if self.args else ""


class InputError(BrdfcorrError, ValueError):
    """An input file or array is missing, unreadable or malformed (the message names it)."""


class ConfigError(BrdfcorrError, ValueError):
    """A chain config is malformed; the message names the file, the key path and what is allowed.
    (Also importable as ``brdfcorr.chain.config.ConfigError``.)"""


class GridMismatchError(BrdfcorrError, ValueError):
    """Input rasters are not on the same grid; the message says which and what differs."""


class OutputError(BrdfcorrError, OSError):
    """An output cannot be written (disk full, file size limit, no permission, or it exists and
    overwriting was not asked for); the message names the file. Nothing partial is left at it."""


class MeasurementError(InputError):
    """A measurement table or measurement array is malformed: a missing column, a non-numeric
    value, an angle outside its domain, a negative or NaN BRDF or uncertainty."""


class SensorInputError(InputError):
    """A sensor product (ENVI obs file, MTD_TL.xml, angle band) lacks an item brdfcorr needs or is
    malformed; the message names the file and the band or element at fault."""


class FitError(BrdfcorrError, RuntimeError):
    """A model fit could not be carried out (no free parameters, no start converged)."""


class BrdfcorrWarning(UserWarning):
    """Root of the warnings brdfcorr issues on purpose (fit diagnostics, guard rails, the papers'
    caveats). The CLI shows these and hides third-party warnings unless ``--debug``."""
