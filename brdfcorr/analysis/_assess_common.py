"""Conventions shared by the assessments of :mod:`brdfcorr.analysis.assess`.

The stage names of their datasets (:data:`STAGES`), the band coordinates the datasets carry
(:func:`_band_coords`), NaN-safe division (:func:`_divide`), and the numbers and band lists of
their JSON reports (:func:`_json_numbers`, :func:`_band_list`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import xarray as xr

#: The two stages compared.
STAGES = ("before", "after")


def _divide(numerator, denominator):
    """``numerator / denominator`` where the denominator is > 0, NaN elsewhere (no warning)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, numerator / np.where(denominator > 0, denominator, 1.0), np.nan)


def _band_coords(cube: xr.DataArray) -> dict[str, Any]:
    """The ``band`` coordinate of a result from a cube (band, y, x): its band numbers (1, 2, ...
    without a coordinate), and ``wavelength`` [nm] if the cube has one."""
    n_bands = cube.shape[0]
    band_dim = cube.dims[0]
    numbers = cube[band_dim].values if band_dim in cube.coords else np.arange(1, n_bands + 1)
    coords: dict[str, Any] = {"band": ("band", np.asarray(numbers))}
    if "wavelength" in cube.coords:
        coords["wavelength"] = ("band", np.asarray(cube["wavelength"].values, float), {"units": "nm"})
    return coords


def _json_numbers(values) -> Any:
    """A number or (nested) list with NaN and infinities as None (valid JSON)."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        value = float(array)
        return value if math.isfinite(value) else None
    return [_json_numbers(item) for item in array]


def _band_list(dataset: xr.Dataset) -> list[dict[str, object]]:
    """The bands of a result for a report: ``band`` number and ``wavelength_nm`` [nm] if known."""
    bands = []
    for index, number in enumerate(dataset["band"].values):
        entry: dict[str, object] = {"band": int(number)}
        if "wavelength" in dataset.coords:
            entry["wavelength_nm"] = float(dataset["wavelength"].values[index])
        bands.append(entry)
    return bands
