"""Which entry point a run came through, so that a message names the fix in the caller's words.

The same check serves the command line, chains and Python (issue 38); its message names the option
that fixes the problem: ``--wavelengths`` on the command line, ``inputs.wavelengths`` in a chain,
``wavelengths=`` in Python. The command line and the chain runner say who they are with
:func:`entered`; Python is the default, so a library function called from a notebook never names
a command-line flag.

>>> option("wavelengths")
'wavelengths='
>>> with entered("cli"):
...     option("wavelengths")
'--wavelengths'
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from typing import Literal

__all__ = ["Entry", "entered", "current", "option"]

Entry = Literal["python", "cli", "chain"]

_ENTRY: ContextVar[Entry] = ContextVar("brdfcorr_entry", default="python")

#: Each fix as the command line, a chain and Python spell it.
_OPTIONS: dict[str, dict[Entry, str]] = {
    "wavelengths": {"cli": "--wavelengths", "chain": "inputs.wavelengths", "python": "wavelengths="},
    "scale": {"cli": "--scale/--offset", "chain": "inputs.scale/inputs.offset",
              "python": "reflectance * scale + offset before the call (or scale=/offset= of "
                        "brdfcorr.io.rasters.open_image)"},
    "scale_example": {"cli": "--scale 0.0001 for reflectance stored as 0-10000 (--scale 1: use them as they are, "
                             "e.g. radiance)",
                      "chain": "scale: 0.0001 for reflectance stored as 0-10000 (scale: 1: use them as they are, "
                               "e.g. radiance)",
                      "python": "a scale of 0.0001 for reflectance stored as 0-10000 (a scale of 1: use them as they "
                                "are, e.g. radiance)"},
    "extrapolate": {"cli": "--extrapolate", "chain": "steps.correct.extrapolate", "python": "extrapolate=True"},
    "align_classes": {"cli": "--align-classes", "chain": "inputs.align_classes: true",
                      "python": "brdfcorr.strata.align_class_map(classes, reflectance)"},
    "angles_kind_envi": {"cli": "--angles-kind envi_obs", "chain": "inputs.angles.kind: envi_obs",
                         "python": "brdfcorr.io.sensors.read_angles('envi_obs', path, like=image)"},
    "degrees": {"cli": "", "chain": "", "python": " (np.degrees converts them)"},
    "bands": {"cli": "--bands", "chain": "bands", "python": "bands="},
    "flip_view_azimuth": {"cli": "--flip-view-azimuth", "chain": "inputs.flip_view_azimuth",
                          "python": "flip_view_azimuth=True"},
    "reference_sza": {"cli": "--ref-sza", "chain": "steps.correct.reference.sza", "python": "reference={'sza': ...}"},
}


@contextmanager
def entered(entry: Entry) -> Iterator[None]:
    """Messages raised inside name the fixes as ``entry`` spells them."""
    token = _ENTRY.set(entry)
    try:
        yield
    finally:
        _ENTRY.reset(token)


def current() -> Entry:
    """The entry point of the running call (``"python"`` unless the CLI or a chain said otherwise)."""
    return _ENTRY.get()


def option(name: str) -> str:
    """The option ``name`` (a key of the fixes table) in the words of the current entry point."""
    return _OPTIONS[name][current()]
