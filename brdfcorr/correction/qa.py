"""The QA flags of a correction: one set of bits for every step (:class:`QA`).

QA layer (uint8 bit flags, CF ``flag_masks``/``flag_meanings`` in its attrs):

==== ================ ========================================================================
bit  name             meaning
==== ================ ========================================================================
1    nodata           nodata (NaN or +-inf) in some band or an angle, or no valid factor in some
                      band (below); output is nodata (in those bands)
2    no_class         class 0 or the class map's nodata ("no class"): not corrected (factor 1,
                      or NaN on request)
4    unknown_class    class id absent from the parameter table: not corrected (1, or NaN)
8    limited          the factor was clipped to the limits in at least one band
16   invalid_geometry a zenith outside [0, 90) deg, or a slope outside [0, 90] deg: output is nodata
32   facing_away      with slope and aspect: the sun or the sensor is at or below the tilted
                      surface's horizon (local zenith >= 90 deg), or with a topographic step
                      cos i <= its ``cos_i_min`` (self-shadowed): output is nodata
64   topography_      with a topographic step before the correction
     uncorrected      (:mod:`brdfcorr.correction.topographic`): the C fit of the pixel's
                      class was rejected in some band (or its C gives the pixel no finite
                      positive factor), which was not corrected for illumination
128  band_            the pixel's class has no parameters in some band (its ``bad_bands`` in
     uncorrected      the parameter table: water vapour, bands the ENVI ``bbl`` marks bad):
                      that band was passed through uncorrected (factor 1, the input value);
                      the other bands were corrected and the pixel counts as corrected
==== ================ ========================================================================

The layer is a uint8 raster; its attrs carry the flags as CF ``flag_masks``/``flag_meanings``
(:func:`qa_attrs`).
"""

from __future__ import annotations

import enum

import dask.array as da
import numpy as np
import xarray as xr

__all__ = ["QA", "set_flags", "qa_attrs", "qa_counts"]


class QA(enum.IntFlag):
    """The QA bits (module docstring). Combine with ``|``, test with ``&``: ``qa & QA.LIMITED``."""

    NODATA = 1
    NO_CLASS = 2
    UNKNOWN_CLASS = 4
    LIMITED = 8
    INVALID_GEOMETRY = 16
    FACING_AWAY = 32
    TOPOGRAPHY_UNCORRECTED = 64
    BAND_UNCORRECTED = 128


def set_flags(qa: np.ndarray, where, flags: QA) -> None:
    """Set ``flags`` in the uint8 QA array ``qa`` at ``where`` (a mask or indices), in place."""
    qa[where] |= np.uint8(flags)  # a uint8 operand: numpy would widen the array's type for an IntFlag


def qa_attrs(long_name: str) -> dict[str, object]:
    """Attributes of a QA layer: its name and the flags as CF ``flag_masks``/``flag_meanings``."""
    return {
        "long_name": long_name,
        "units": "1",
        "flag_masks": np.array([flag.value for flag in QA], dtype=np.uint8),
        "flag_meanings": " ".join(str(flag.name).lower() for flag in QA),
    }


def qa_counts(qa) -> dict[str, object]:
    """Pixel counts per QA outcome (lazy 0-d arrays for dask input; compute them together).

    ``corrected``: pixels with a class of the table, valid data and a valid factor in every band
    (limited ones included); ``limited``, ``unknown_class``, ``no_class``, ``nodata`` (nodata, no
    valid factor, invalid geometry, or a tilted surface facing away from the sun or the sensor).
    """
    data = qa.data if isinstance(qa, xr.DataArray) else qa
    xp = da if isinstance(data, da.Array) else np
    skipped = QA.NODATA | QA.NO_CLASS | QA.UNKNOWN_CLASS | QA.INVALID_GEOMETRY | QA.FACING_AWAY
    return {
        "corrected": xp.count_nonzero((data & skipped) == 0),
        "limited": xp.count_nonzero(data & QA.LIMITED),
        "unknown_class": xp.count_nonzero(data & QA.UNKNOWN_CLASS),
        "no_class": xp.count_nonzero(data & QA.NO_CLASS),
        "nodata": xp.count_nonzero(data & (QA.NODATA | QA.INVALID_GEOMETRY | QA.FACING_AWAY)),
    }

