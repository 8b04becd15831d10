"""An output written as ENVI: its layout (:class:`EnviOutput`), the header fields GDAL's ENVI
driver does not write (wavelengths, FWHM, bad band list, a description naming the output), what a
header cannot say (:func:`check_envi_georeference`) or must not hold (band names that would add
fields), and the copy of the header GDAL keeps in the ``.aux.xml``, removed. The text of a band
centre in any output, GeoTIFF tags included: :func:`wavelength_text`. Used by
:mod:`brdfcorr.io.writer`, which writes the files.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal
from xml.etree import ElementTree

import numpy as np
import rasterio
import rasterio.errors
import rasterio.warp
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from rasterio._err import CPLE_BaseError  # GDAL errors rasterio passes on as they are

from brdfcorr.errors import InputError, OutputError

__all__ = ["EnviOutput", "wavelength_text", "check_envi_georeference"]


@dataclass(frozen=True)
class EnviOutput:
    """How :func:`brdfcorr.io.writer.write_rasters` writes a target as ENVI.

    Attributes
    ----------
    interleave : {"bsq", "bil"}
        Band sequential or band interleaved by line.
    wavelength, fwhm : sequence of float, optional
        Band centres and full widths at half maximum [nm], written to the header as
        ``wavelength``, ``fwhm`` and ``wavelength units = Nanometers``.
    bad_bands : sequence of bool, optional
        Which bands are bad (the input header's bad band list), written as ``bbl`` (1 good, 0 bad).
    """

    interleave: Literal["bsq", "bil"] = "bsq"
    wavelength: Sequence[float] | None = None
    fwhm: Sequence[float] | None = None
    bad_bands: Sequence[bool] | None = None


def wavelength_text(value: float) -> str:
    """A band centre or width [nm] as written into an output (tags, band descriptions, ENVI
    headers): the shortest text that reads back as the same number (``1234.5678``, ``480``), where
    ``:g`` kept 6 digits (1234.57)."""
    return np.format_float_positional(float(value), trim="-")


def _header_list(values: Sequence[float]) -> str:
    return "{" + ", ".join(wavelength_text(value) for value in values) + "}"


def write_envi_header(path: Path, layout: EnviOutput, final: Path) -> None:
    """Add the spectral fields to the header GDAL wrote (GDAL rewrites it on close): items of the
    dataset's ENVI metadata domain are header fields (GDAL's ENVI driver). Then replace the
    ``description`` GDAL fills with the file's (temporary) path by the final file's name, made safe
    for a header (:func:`_header_text`)."""
    items = {}
    if layout.wavelength is not None:
        items.update(wavelength=_header_list(layout.wavelength), wavelength_units="Nanometers")
    if layout.fwhm is not None:
        items["fwhm"] = _header_list(layout.fwhm)
    if layout.bad_bands is not None:
        items["bbl"] = _header_list([not bad for bad in layout.bad_bands])
    if items:
        with rasterio.open(path, "r+") as dataset:
            dataset.update_tags(ns="ENVI", **items)
    header = Path(f"{path}.hdr")
    text = header.read_text()
    written = f"description = {{\n{path}}}\n"
    if written not in text:
        raise OutputError(f"cannot write {final}: GDAL's ENVI header {header} has no description of the file")
    header.write_text(text.replace(written, f"description = {{\nbrdfcorr output {_header_text(final.name)}}}\n", 1))


def header_fields_in_header_only(aux: Path) -> None:
    """Remove from an ENVI output's ``.aux.xml`` the copies GDAL keeps there of what its header
    holds: the ENVI metadata domain (every header field, the ``description`` with the temporary
    file's name) and each band's nodata (``data ignore value``). GDAL reads the ``.aux.xml`` over
    the header, so a header edited later (its ``wavelength``, its ``data ignore value``) was not
    what GDAL and brdfcorr read. The provenance tags and the band descriptions stay (without
    them GDAL would describe each band by its name and wavelength, ``480 nm (480 Nanometers)``)."""
    if not aux.is_file():
        return
    tree = ElementTree.parse(aux)
    root = tree.getroot()
    for element in root.findall("Metadata[@domain='ENVI']"):
        root.remove(element)
    for band in root.findall("PAMRasterBand"):
        for element in band.findall("NoDataValue"):
            band.remove(element)
        if not len(band):
            root.remove(band)
    tree.write(aux, encoding="unicode")


def _header_text(text: str) -> str:
    """Text that cannot end or add an ENVI header field: braces become parentheses, commas (which
    separate a list's items) semicolons, line breaks spaces."""
    table = str.maketrans({"{": "(", "}": ")", ",": ";", "\n": " ", "\r": " "})
    return str(text).translate(table)


def envi_safe(array: xr.DataArray) -> xr.DataArray:
    """The array with band descriptions (the header's ``band names``) that cannot inject header fields."""
    names = array.attrs.get("long_name")
    if not isinstance(names, (tuple, list)):
        return array
    safe = array.copy(deep=False)
    safe.attrs = {**array.attrs, "long_name": tuple(_header_text(name) for name in names)}
    return safe


def check_envi_georeference(array: xr.DataArray, target: str | os.PathLike) -> None:
    """Refuse what an ENVI header cannot say: its ``map info`` holds pixel sizes and one rotation,
    so a sheared geotransform (columns not perpendicular to rows) would be written as a rotation
    (tens of metres off at the far corner), and a raster with a geotransform but no CRS would get
    ``map info = {Arbitrary, ...}``, read back as a local CRS ``LOCAL_CS["Arbitrary"]``. Other
    geotransforms are written to a one-pixel ENVI file in a scratch folder and read back
    (:func:`_read_back`): GDAL reads a mirrored grid (columns running west) and one turned by
    180 degrees back as another, while a south-up grid and other rotations come back as written.

    Raises
    ------
    InputError
        Naming the output, with the GeoTIFF format as the way out.
    """
    transform = array.rio.transform()
    a, b, d, e = transform.a, transform.b, transform.d, transform.e
    if abs(a * b + d * e) > 1e-9 * max(a * a + d * d, b * b + e * e):
        raise InputError(f"ENVI output {target}: the image's geotransform is sheared ({tuple(transform)[:6]}); an "
                         "ENVI header holds pixel sizes and a rotation only; write a GeoTIFF (--format GTiff)")
    if array.rio.crs is None and not transform.is_identity:
        raise InputError(f"ENVI output {target}: the image has no CRS; an ENVI header would say 'Arbitrary', read "
                         "back as a local CRS; write a GeoTIFF (--format GTiff) or give the image a CRS")
    if transform.is_identity:
        return
    back, back_crs = _read_back(transform, array.rio.crs)
    pixel = max(abs(a), abs(b), abs(d), abs(e))
    if not np.allclose(tuple(back)[:6], tuple(transform)[:6], rtol=0, atol=1e-6 * pixel):
        raise InputError(f"ENVI output {target}: an ENVI header does not hold the image's geotransform "
                         f"({tuple(transform)[:6]}; GDAL reads it back as {tuple(back)[:6]}: columns running west, "
                         "or a grid turned by 180 degrees); write a GeoTIFF (--format GTiff)")
    # The CRS as read back, where the corner lands: EPSG:2263 (US survey feet) came back in
    # international feet, every pixel 0.6 m off at 980 000 ft.
    if back_crs != array.rio.crs and not _same_place(back_crs, array.rio.crs, transform.c, transform.f, pixel):
        raise InputError(f"ENVI output {target}: an ENVI header does not hold the image's CRS "
                         f"({array.rio.crs.to_string()}: GDAL reads it back as another, which puts the corner "
                         "elsewhere); write a GeoTIFF (--format GTiff)")


def _same_place(back_crs, crs, x: float, y: float, pixel: float) -> bool:
    """Whether the point (x, y) of ``crs`` read in ``back_crs`` lies within a thousandth of a pixel
    of itself: a CRS read back described otherwise but equivalent; False where no operation
    relates the two (a local CRS read back as another)."""
    try:
        (x_back,), (y_back,) = rasterio.warp.transform(back_crs, crs, [x], [y])
    except (rasterio.errors.CRSError, CPLE_BaseError):
        return False
    return bool(np.hypot(x_back - x, y_back - y) <= 1e-3 * pixel)


def _read_back(transform, crs):
    """The geotransform and CRS GDAL reads from an ENVI header it wrote with ``transform`` and ``crs``."""
    with tempfile.TemporaryDirectory(prefix="brdfcorr-envi-") as scratch:
        path = Path(scratch) / "probe.img"
        with rasterio.open(path, "w", driver="ENVI", width=1, height=1, count=1, dtype="uint8", crs=crs,
                           transform=transform) as probe:
            probe.write(np.zeros((1, 1, 1), np.uint8))
        with rasterio.open(path) as probe:
            return probe.transform, probe.crs
