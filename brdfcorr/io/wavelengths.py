"""Band-centre wavelengths [nm] of an image, from the sources of ``docs/conventions.md`` in their
order (:func:`band_wavelengths`), and of one band description (:func:`parse_wavelength`)."""

from __future__ import annotations

import os
import re
from collections.abc import Mapping, Sequence

import numpy as np
import xarray as xr

from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io.opening import opened
from brdfcorr.io.sensors.bands import (
    LANDSAT_OLI_WAVELENGTHS,
    MICROMETRES_BELOW,
    SENTINEL2_WAVELENGTHS,
    UNITS_TO_NM,
    named_band_wavelengths,
)

__all__ = ["band_wavelengths", "file_wavelengths", "with_wavelengths", "matched_bands", "envi_header_wavelengths",
           "envi_fwhm", "tag_fwhm", "parse_wavelength", "LANDSAT_OLI_WAVELENGTHS", "SENTINEL2_WAVELENGTHS"]

_NUMBER = r"[0-9]+(?:\.[0-9]*)?(?:[eE][+-]?[0-9]+)?"
_UNIT = r"nm|um|µm|μm|nanomet(?:er|re)s?|micromet(?:er|re)s?|microns?"
#: A wavelength in a description: a range (its two ends, the unit after the second) or one number, with a unit.
_IN_TEXT = re.compile(rf"({_NUMBER})(?:\s*(?:{_UNIT}))?\s*(?:-|–|to)\s*({_NUMBER})\s*({_UNIT})\b"
                      rf"|({_NUMBER})\s*({_UNIT})\b", re.I)


def parse_wavelength(text: str) -> float | None:
    """A band-centre wavelength [nm] from a band description, or None.

    Accepts a number with an optional unit (``"560"``, ``"560 nm"``, ``"0.56 um"``), or a
    description containing one number followed by a unit (``"B3 (560 nm)"``) or one range
    (``"Blue 460-500 nm"``, ``"0.455 to 0.505 um"``: its middle, 480 nm; its upper end was taken
    for the centre before). ``"Band 3"`` is not a wavelength, nor is a description that gives two
    or more (``"FWHM 10 nm, centre 480 nm"``): which is the centre is not said.
    """
    if not text:
        return None
    text = text.strip()
    match = re.fullmatch(rf"({_NUMBER})\s*([A-Za-zµμ]*)", text)
    if match is not None:
        unit = UNITS_TO_NM.get(match[2].lower())
        return None if unit is None else float(match[1]) * unit
    found = [(float(low) + float(high)) / 2 * UNITS_TO_NM[unit.lower()] if low else
             float(number) * UNITS_TO_NM[single.lower()]
             for low, high, unit, number, single in _IN_TEXT.findall(text)]
    return found[0] if len(found) == 1 else None


def band_wavelengths(image: xr.DataArray, path: str | os.PathLike | None = None,
                     explicit: Sequence[float] | None = None) -> np.ndarray | None:
    """Band-centre wavelengths [nm] of an image, or None when nothing gives them.

    Sources, in the order of ``docs/conventions.md``: ``explicit``; a dataset tag ``wavelength`` with
    comma-separated values (``wavelength_units`` tag honoured, nm by default); the ``wavelength``
    item of an ENVI image's header (:func:`envi_header_wavelengths`: before the band descriptions
    GDAL makes of it, which lose its units); band descriptions holding a number with an optional
    unit; band descriptions that are band names, Landsat 8/9 OLI names (``SR_B1`` ... ``SR_B7``,
    ``B1`` ...; :data:`LANDSAT_OLI_WAVELENGTHS`) where a dataset tag ``sensor`` or ``SENSOR_ID``
    says ``OLI``, else Sentinel-2 names (``B02``, ``B2``, ``B8A``; Sentinel-2A centres,
    :data:`SENTINEL2_WAVELENGTHS`) when every band has one. Band names that fit neither rule (a mix,
    ``SR_B4`` without the sensor) give no wavelengths rather than a guess.

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


#: Band centres [nm] closer than this are one band (rounding in a header or a tag).
SAME_BAND_NM = 1e-3


def matched_bands(image: xr.DataArray, like: xr.DataArray, names: tuple[str, str], why: str = "") -> xr.DataArray:
    """``image`` with its bands in the order of ``like``'s: by their ``wavelength`` coordinates [nm]
    where both have one (a file whose bands are stored in another order; the same band within
    :data:`SAME_BAND_NM`), else by position. The band dimension is the third from last.

    Raises
    ------
    InputError
        The band counts differ (``"{names[0]} has 3 bands, {names[1]} has 4"``), or the bands are
        not the same wavelengths (both named, with the band centres); ``why`` ends the message.
    """
    band = image.dims[-3]
    count, wanted = image.sizes[band], like.sizes[like.dims[-3]]
    if count != wanted:
        raise InputError(f"{names[0]} has {count} bands, {names[1]} has {wanted}{why}")
    if "wavelength" not in image.coords or "wavelength" not in like.coords:
        return image
    mine = np.atleast_1d(np.asarray(image["wavelength"].values, dtype=float))
    theirs = np.atleast_1d(np.asarray(like["wavelength"].values, dtype=float))
    order = [int(np.argmin(np.abs(mine - centre))) for centre in theirs]
    if len(set(order)) != count or not np.allclose(mine[order], theirs, rtol=0, atol=SAME_BAND_NM):
        raise InputError(f"{names[0]} has its bands at {_listed(mine)} nm, {names[1]} at {_listed(theirs)} nm: "
                         f"not the same bands{why}")
    return image if order == list(range(count)) else image.isel({band: order})


def _listed(centres) -> str:
    """Band centres [nm] for a message: ``480, 560, 660``."""
    return ", ".join(f"{value:.6g}" for value in centres)


def _refuse_micrometres_as_nm(coordinate: xr.DataArray) -> None:
    """An :class:`InputError` for a ``wavelength`` coordinate without a unit whose values all lie
    below 100: micrometres read as nanometres would put every band outside a table's wavelengths."""
    try:
        values = np.asarray(coordinate.values, dtype=float)
    except (TypeError, ValueError):
        return
    finite = values[np.isfinite(values)]
    if "units" not in coordinate.attrs and finite.size and np.all(finite < MICROMETRES_BELOW):
        raise InputError(f"the wavelength coordinate ({finite.min():g} ... {finite.max():g}) has no units and lies "
                         f"below {MICROMETRES_BELOW:g}: micrometres? Set its units, e.g. "
                         "reflectance['wavelength'].attrs['units'] = 'um', or give it in nm")


def with_wavelengths(array: xr.DataArray) -> xr.DataArray:
    """``array`` with a ``wavelength`` coordinate [nm] where it carries its band centres otherwise.

    Its own ``wavelength`` coordinate is read in the unit of its ``units`` attribute (nm without
    one); without it, STAC's ``center_wavelength`` [µm] (``eo:bands``, as stackstac and odc-stac
    give it) where every band has one, else the band dimension's labels where they are Sentinel-2
    band names (``"B04"``; :func:`~brdfcorr.io.sensors.bands.named_band_wavelengths`). An array
    with none of them is returned as it is. The band dimension is the third from last: (band, y,
    x) or (time, band, y, x).

    Raises
    ------
    InputError
        A ``wavelength`` coordinate in a unit other than nm or µm, or one without a unit whose
        values all lie below 100 (micrometres, as an ENVI header without units holds them; no band
        of an optical sensor is centred below 100 nm).
    """
    if "wavelength" in array.coords and array["wavelength"].dtype.kind in "OUS":  # text: "480 nm", "0.48 um"
        coordinate = array["wavelength"]
        parsed = [parse_wavelength(str(label)) for label in np.atleast_1d(coordinate.values)]
        if any(value is None for value in parsed):
            bad = next(label for label, value in zip(np.atleast_1d(coordinate.values), parsed) if value is None)
            raise InputError(f"the wavelength coordinate holds {str(bad)!r}, no band centre: give numbers [nm] (or "
                             "text such as '480 nm')")
        return array.assign_coords(wavelength=(coordinate.dims, np.asarray(parsed, dtype=float).reshape(
            coordinate.shape), {"units": "nm"}))
    if "wavelength" in array.coords:
        coordinate = array["wavelength"]
        unit = str(coordinate.attrs.get("units", "nm")).strip().lower()
        if unit not in UNITS_TO_NM:
            raise InputError(f"the wavelength coordinate is in {unit!r}: give it in nm or µm (its 'units' attribute)")
        if UNITS_TO_NM[unit] == 1.0:
            _refuse_micrometres_as_nm(coordinate)
            return array
        nm = np.asarray(coordinate.values, dtype=float) * UNITS_TO_NM[unit]
        return array.assign_coords(wavelength=(coordinate.dims, nm, {**coordinate.attrs, "units": "nm"}))
    band = array.dims[-3] if array.ndim >= 3 else None
    if "center_wavelength" in array.coords:
        coordinate = array["center_wavelength"]
        try:
            microns = np.asarray(coordinate.values, dtype=float)
        except (TypeError, ValueError):  # a band without one (None): not every band is spectral
            microns = np.array([np.nan])
        if np.all(np.isfinite(microns) & (microns > 0)):
            return array.assign_coords(wavelength=(coordinate.dims, 1e3 * microns, {"units": "nm"}))
    if band is not None and band in array.coords and array[band].dtype.kind in "OUS":
        named, _ = named_band_wavelengths([str(label) for label in array[band].values], {})
        if named is not None:
            return array.assign_coords(wavelength=(band, np.asarray(named, dtype=float), {"units": "nm"}))
    return array


def envi_header_wavelengths(path) -> tuple[np.ndarray, np.ndarray | None]:
    """Band centres and FWHM [nm] of an ENVI image's header in its units
    (:func:`brdfcorr.io.sensors.envi.envi_wavelengths`), an :class:`InputError` where it is malformed."""
    from brdfcorr.io.sensors.envi import envi_wavelengths

    try:
        return envi_wavelengths(path)
    except BrdfcorrError as error:
        raise InputError(str(error)) from None


def tag_fwhm(tags: Mapping, n_bands: int, source) -> np.ndarray:
    """The bands' FWHM [nm] of the dataset tag ``fwhm`` (comma-separated, in the ``wavelength_units``
    of the band centres, nm by default; as a brdfcorr GeoTIFF output writes it).

    Raises
    ------
    InputError
        A ``fwhm`` tag that is not one positive number per band, or unknown units.
    """
    values = np.array(_tag_nanometres(tags, "fwhm", source))
    if values.size != n_bands or not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"{source}: tag fwhm={tags['fwhm']!r} is not one positive width per band ({n_bands} bands)")
    return values


def _tag_nanometres(tags: Mapping, key: str, source) -> list[float]:
    """The comma-separated numbers of the dataset tag ``key`` in nm (read in the ``wavelength_units``
    tag's unit, nm by default); an :class:`InputError` for text that is no list of numbers or an
    unknown unit."""
    text = str(tags[key])
    try:
        values = [float(v) for v in re.split(r"[,\s]+", text.strip(" {}[]()")) if v]
    except ValueError:
        raise InputError(f"{source}: tag {key}={text!r} is not a comma-separated list of numbers") from None
    unit = str(tags.get("wavelength_units", "nm")).strip().lower()
    if unit not in UNITS_TO_NM:
        raise InputError(f"{source}: unknown wavelength_units {unit!r}")
    return [v * UNITS_TO_NM[unit] for v in values]


def _refuse_contradiction(tagged: Sequence[float], descriptions, source) -> None:
    """An :class:`InputError` where the band descriptions, each a wavelength with its unit, are
    the ``wavelength`` tag's band centres in another order (each nearest to another band's centre,
    within rounding): ``gdal_translate -b 3 -b 2 -b 1`` reorders the descriptions with the bands
    and copies the dataset's tags as they are, so the tag names the bands in the old order. Other
    differences (descriptions rounded, or not wavelengths of these bands) leave the tag's, which
    takes precedence."""
    described = [parse_wavelength(text) if text and re.search(rf"(?:{_UNIT})\b", text, re.I) else None
                 for text in descriptions or ()]
    if len(described) != len(tagged) or len(tagged) < 2 or any(value is None for value in described):
        return
    centres, found = np.asarray(tagged, dtype=float), np.asarray(described, dtype=float)
    order = np.argmin(np.abs(centres[None, :] - found[:, None]), axis=1)
    spacing = np.min(np.diff(np.sort(centres)))
    reordered = (len(set(order.tolist())) == len(order) and np.any(order != np.arange(len(order)))
                 and np.all(np.abs(centres[order] - found) < spacing / 2))
    if reordered:
        raise InputError(f"{source}: tag 'wavelength' says {_listed(centres)} nm and the band descriptions "
                         f"{_listed(found)} nm: the bands were reordered without the tag? Correct the tag "
                         "(gdal_edit.py -mo wavelength=...) or give the wavelengths")


def envi_fwhm(path) -> np.ndarray | None:
    """The FWHM [nm] of an ENVI image's header, None where it holds none or no band centres to
    tell its units by (:func:`envi_header_wavelengths`)."""
    try:
        return envi_header_wavelengths(path)[1]
    except InputError:
        return None


def _from_metadata(n_bands: int, tags, descriptions, envi_header, path, source, explicit) -> np.ndarray | None:
    """:func:`band_wavelengths` from what the image or file holds."""
    values = None
    origin = ""
    if explicit is not None:
        values, origin = [float(v) for v in explicit], "the given wavelengths"
    elif "wavelength" in tags:
        values, origin = _tag_nanometres(tags, "wavelength", source), "tag 'wavelength'"
        _refuse_contradiction(values, descriptions, source)
    elif "wavelength" in envi_header:  # before the band descriptions GDAL makes of it, without its units
        values, origin = envi_header_wavelengths(path)[0].tolist(), "ENVI header"
    else:
        parsed = [parse_wavelength(d or "") for d in descriptions] if descriptions else []
        named, named_origin = named_band_wavelengths(descriptions, tags)
        if parsed and all(p is not None for p in parsed):
            values, origin = parsed, "band descriptions"
        elif named is not None:
            values, origin = named, named_origin
    if values is None:
        return None
    if len(values) != n_bands:
        raise InputError(f"{source}: {len(values)} wavelengths from {origin} for {n_bands} bands")
    values = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(values) & (values > 0)):
        raise InputError(f"{source}: wavelengths from {origin} must be finite and > 0 nm")
    return values
