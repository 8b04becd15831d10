"""Band-centre wavelengths [nm] of an image, from the sources of ``docs/conventions.md`` in their
order (:func:`band_wavelengths`), and of one band description (:func:`parse_wavelength`)."""

from __future__ import annotations

import os
import re
from collections.abc import Sequence

import numpy as np
import xarray as xr

from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io.opening import opened
from brdfcorr.io.sensors.bands import LANDSAT_OLI_WAVELENGTHS, SENTINEL2_WAVELENGTHS, named_band_wavelengths

__all__ = ["band_wavelengths", "file_wavelengths", "parse_wavelength", "LANDSAT_OLI_WAVELENGTHS",
           "SENTINEL2_WAVELENGTHS"]

_UNITS_TO_NM = {
    "": 1.0, "nm": 1.0, "nanometer": 1.0, "nanometers": 1.0, "nanometre": 1.0, "nanometres": 1.0,
    "um": 1e3, "µm": 1e3, "μm": 1e3, "micron": 1e3, "microns": 1e3, "micrometer": 1e3,
    "micrometers": 1e3, "micrometre": 1e3, "micrometres": 1e3,
}
_NUMBER = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?"


def parse_wavelength(text: str) -> float | None:
    """A band-centre wavelength [nm] from a band description, or None.

    Accepts a number with an optional unit (``"560"``, ``"560 nm"``, ``"0.56 um"``), or a
    description containing a number followed by a unit (``"B3 (560 nm)"``). ``"Band 3"`` is not a
    wavelength.
    """
    if not text:
        return None
    text = text.strip()
    match = re.fullmatch(rf"({_NUMBER})\s*([A-Za-zµμ]*)", text)
    if match is None:
        match = re.search(rf"({_NUMBER})\s*(nm|um|µm|μm|nanometers?|micrometers?|microns?)\b", text, re.I)
    if match is None or match[2].lower() not in _UNITS_TO_NM:
        return None
    return float(match[1]) * _UNITS_TO_NM[match[2].lower()]


def band_wavelengths(image: xr.DataArray, path: str | os.PathLike | None = None,
                     explicit: Sequence[float] | None = None) -> np.ndarray | None:
    """Band-centre wavelengths [nm] of an image, or None when nothing gives them.

    Sources, in the order of ``docs/conventions.md``: ``explicit``; a dataset tag ``wavelength`` with
    comma-separated values (``wavelength_units`` tag honoured, nm by default); band descriptions
    holding a number with an optional unit; band descriptions that are band names, Landsat 8/9 OLI
    names (``SR_B1`` ... ``SR_B7``, ``B1`` ...; :data:`LANDSAT_OLI_WAVELENGTHS`) where a dataset tag
    ``sensor`` or ``SENSOR_ID`` says ``OLI``, else Sentinel-2 names (``B02``, ``B2``, ``B8A``;
    Sentinel-2A centres, :data:`SENTINEL2_WAVELENGTHS`) when every band has one; the ENVI header of
    an ENVI image. Band names that fit neither rule (a mix, ``SR_B4`` without the sensor) give no
    wavelengths rather than a guess.

    Raises
    ------
    InputError
        A source is present but malformed, or gives a count other than the number of bands.
    """
    n_bands = image.sizes[image.dims[0]]
    source = path or image.encoding.get("source", "image")
    if path is not None:
        _, tags, descriptions, envi_header = _file_metadata(path)
    else:
        tags, envi_header = image.attrs, {}
        descriptions = image.attrs.get("long_name")
        if isinstance(descriptions, str):
            descriptions = (descriptions,) if n_bands == 1 else None
    return _from_metadata(n_bands, tags, descriptions, envi_header, path, source, explicit)


def file_wavelengths(path: str | os.PathLike) -> np.ndarray | None:
    """Band-centre wavelengths [nm] of a raster file (its tags, band descriptions or ENVI header:
    the file sources of :func:`band_wavelengths`), or None when nothing gives them."""
    return _from_metadata(*_file_metadata(path), path, path, None)


def _file_metadata(path) -> tuple[int, dict, tuple, dict]:
    """A file's band count, dataset-level tags (rioxarray's attrs mix in the tags of band 1), band
    descriptions and ENVI header items."""
    with opened(path, "image") as dataset:
        envi_header = dataset.tags(ns="ENVI") if dataset.driver == "ENVI" else {}
        return dataset.count, dataset.tags(), dataset.descriptions, envi_header


def _from_metadata(n_bands: int, tags, descriptions, envi_header, path, source, explicit) -> np.ndarray | None:
    """:func:`band_wavelengths` from what the image or file holds."""
    values = None
    origin = ""
    if explicit is not None:
        values, origin = [float(v) for v in explicit], "the given wavelengths"
    elif "wavelength" in tags:
        text = str(tags["wavelength"])
        try:
            values = [float(v) for v in re.split(r"[,\s]+", text.strip(" {}[]()")) if v]
        except ValueError:
            raise InputError(f"{source}: tag wavelength={text!r} is not a comma-separated list of numbers") from None
        unit = str(tags.get("wavelength_units", "nm")).strip().lower()
        if unit not in _UNITS_TO_NM:
            raise InputError(f"{source}: unknown wavelength_units {unit!r}")
        values = [v * _UNITS_TO_NM[unit] for v in values]
        origin = "tag 'wavelength'"
    else:
        parsed = [parse_wavelength(d or "") for d in descriptions] if descriptions else []
        named, named_origin = named_band_wavelengths(descriptions, tags)
        if parsed and all(p is not None for p in parsed):
            values, origin = parsed, "band descriptions"
        elif named is not None:
            values, origin = named, named_origin
        elif "wavelength" in envi_header:
            from brdfcorr.io.sensors.envi import envi_wavelengths

            try:
                values, origin = envi_wavelengths(path)[0].tolist(), "ENVI header"
            except BrdfcorrError as error:
                raise InputError(str(error)) from None
    if values is None:
        return None
    if len(values) != n_bands:
        raise InputError(f"{source}: {len(values)} wavelengths from {origin} for {n_bands} bands")
    values = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"{source}: wavelengths from {origin} must be finite and > 0 nm")
    return values
