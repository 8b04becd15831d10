"""Reflectance images and class maps as rioxarray reads them.

Readers open lazily (dask chunks), with nodata as NaN for reflectance and the class map kept as
integers with its nodata value; the image's stored values are scaled to reflectance factors (the
file's GDAL scale/offset, or given ones) and an undeclared fill value refused as the chunks are
computed (:mod:`brdfcorr.io.reflectance`; :func:`brdfcorr.io.scale_check.check_reflectance_scale`
catches raw counts), its band centres found by :func:`brdfcorr.io.wavelengths.band_wavelengths`. Angles:
:mod:`brdfcorr.io.angles`; the grid check: :mod:`brdfcorr.io.grid`; a whole scene:
:func:`brdfcorr.io.scene.open_scene`; writing: :mod:`brdfcorr.io.writer`. An image identified once
(product kind, layout) and the chunk and cache sizes of its reading: :mod:`brdfcorr.io.product`
(its names are importable from here as well).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import xarray as xr

from brdfcorr.errors import InputError
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.opening import chunk_spec, has_envi_header, open_raster
from brdfcorr.io.product import (  # the identification and sizes, importable from here as they were
    CHUNK_TARGET,
    MAX_GDAL_CACHE,
    MIN_GDAL_CACHE,
    ImageFile,
    Layout,
    _read_as_stored,
    auto_chunk,
    bounded_gdal_cache,
    cache_bytes,
    choose_chunk,
    gdal_cache_bytes,
    header_scale,
    identify_image,
    image_layout,
    peak_memory_terms,
)
from brdfcorr.io.reflectance import as_reflectance, refuse_fill
from brdfcorr.io.sensors.envi import envi_bad_bands
from brdfcorr.io.sensors.products import hdf5_product, open_product
from brdfcorr.io.wavelengths import band_wavelengths, envi_fwhm, tag_fwhm
from brdfcorr.io.writer import DEFAULT_CHUNK, GeoTiffOutput, write_rasters

__all__ = [
    "open_image",
    "open_classes",
    "auto_chunk",
    "choose_chunk",
    "Layout",
    "ImageFile",
    "identify_image",
    "image_layout",
    "cache_bytes",
    "gdal_cache_bytes",
    "bounded_gdal_cache",
    "peak_memory_terms",
    "CHUNK_TARGET",
    "MIN_GDAL_CACHE",
    "MAX_GDAL_CACHE",
    "write_rasters",
    "GeoTiffOutput",
    "DEFAULT_CHUNK",
]


def open_image(path, chunks=None, wavelengths: Sequence[float] | None = None, *, scale: float | None = None,
               offset: float | None = None) -> xr.DataArray:
    """Open a reflectance image (band, y, x) lazily as reflectance factors [1], nodata as NaN, with a
    ``wavelength`` coord.

    Stored values are turned into reflectance factors with the file's per-band GDAL scale and
    offset (``reflectance = stored * scale + offset``, as rioxarray's ``mask_and_scale`` does; 1 and
    0 where the file tags none; for an ENVI image without them, 1 / its header's ``reflectance
    scale factor``: :func:`~brdfcorr.io.product.header_scale`), after masking nodata. ``scale`` and
    ``offset`` are for products that do not tag them: a given value replaces the file's for every
    band (an explicit scale wins over a different tagged one), one not given stays the file's.

    A NEON AOP reflectance HDF5 (``.h5``) or an EMIT L2A reflectance NetCDF (``.nc``), told by
    content, is opened by its reader instead (:func:`brdfcorr.io.sensors.read_neon_image`,
    :func:`brdfcorr.io.sensors.read_emit_image`: the product's scale and nodata, wavelengths and
    FWHM, CRS and transform; EMIT's swath orthorectified onto its GLT grid); ``scale``/``offset``
    given replace the product's.

    Parameters
    ----------
    path : path-like or ImageFile
        Any raster GDAL reads (GeoTIFF, ENVI, ...), or a NEON ``.h5`` / EMIT ``.nc`` image; or
        such a file identified already (:func:`identify_image`: not looked at again).
    chunks : int or dict, optional
        Dask chunks; an int is the spatial chunk size with all bands in one chunk (default 512).
    wavelengths : sequence of float, optional
        Band centres [nm], overriding what the file says (:func:`brdfcorr.io.wavelengths.band_wavelengths`).
    scale : float, optional
        Reflectance factor per stored unit [1] (> 0), e.g. 0.0001 for reflectance stored as
        0-10000 (default: the file's).
    offset : float, optional
        Reflectance factor of a stored 0 [1], e.g. -0.2 for Landsat Collection 2 level 2
        (default: the file's).

    Returns
    -------
    DataArray
        float32 (float64 for a float64 file), with attrs ``brdf_input_scale`` and
        ``brdf_input_offset``: the scale and offset applied (a float, or a tuple of one per band
        where the bands differ). Each chunk, as it is computed, raises :class:`InputError` for
        values below :data:`FILL_FLOOR` (an undeclared nodata value: :func:`refuse_fill`).
    """
    identified = path if isinstance(path, ImageFile) else None
    path = path if identified is None else identified.path
    _check_given_scaling(path, scale, offset)
    if identified is not None:
        product = identified.product
    else:
        product = hdf5_product(path) if Path(path).exists() else None
    if product is not None:
        return refuse_fill(open_product(product, path, chunk_spec(chunks), wavelengths, scale, offset), f"image {path}")
    if scale is None:  # an ENVI header's reflectance scale factor, where it has one
        scale = identified.header_scale if identified is not None else header_scale(path)
    given = scale is not None or offset is not None
    as_stored = not given and (identified.plain if identified is not None else _read_as_stored(path))
    image = open_raster(path, "image", chunk_spec(chunks), masked=not as_stored,
                        mask_and_scale=not (given or as_stored))
    found = band_wavelengths(image, path, wavelengths)  # from the file's metadata: before or after the scaling
    image = as_reflectance(image, scale, offset, as_stored)
    if found is not None:
        image = image.assign_coords(wavelength=(image.dims[0], found, {"units": "nm"}))
    if "fwhm" in image.coords:  # rioxarray's, from an ENVI header: in the header's units
        fwhm = envi_fwhm(path)
        image = image.drop_vars("fwhm") if fwhm is None else image.assign_coords(
            fwhm=(image.dims[0], fwhm, {"units": "nm"}))
    elif "fwhm" in image.attrs:  # a GeoTIFF's tag (a brdfcorr output's)
        fwhm = tag_fwhm(image.attrs, image.sizes[image.dims[0]], path)
        image = image.assign_coords(fwhm=(image.dims[0], fwhm, {"units": "nm"}))
        image.attrs = {key: value for key, value in image.attrs.items() if key != "fwhm"}
    image.name = image.name or "reflectance"
    if identified is not None:
        bad = identified.bad_bands
    else:
        bad = envi_bad_bands(path) if has_envi_header(path) else None
    return refuse_fill(image, f"image {path}", bad)


def _check_given_scaling(path, scale: float | None, offset: float | None) -> None:
    """A given scale and offset are finite, the scale > 0 (an :class:`InputError` naming the image)."""
    for name, value in (("scale", scale), ("offset", offset)):
        if value is not None and not math.isfinite(value):
            raise InputError(f"image {path}: the given {name} {value} is not a finite number")
    if scale is not None and scale <= 0:
        raise InputError(f"image {path}: the given scale {scale} must be > 0")


def open_classes(path, chunks=None) -> xr.DataArray:
    """Open a class map (y, x) lazily, keeping its integer values and its nodata (``.rio.nodata``)."""
    classes = open_raster(path, "class map", chunk_spec(chunks), masked=False)
    if classes.sizes[classes.dims[0]] != 1:
        raise InputError(f"class map {path} has {classes.sizes[classes.dims[0]]} bands; it needs 1")
    if classes.dtype.kind not in "iu":  # a float map is usually a reflectance or a resampled map
        raise InputError(
            f"class map {path} has data type {classes.dtype}; it needs integer class ids "
            "(uint8, uint16, int16, ...): convert it, e.g. gdal_translate -ot UInt16"
        )
    nodata = classes.rio.nodata
    classes = classes.isel({classes.dims[0]: 0}, drop=True)
    classes.name = "classes"
    return classes.rio.write_nodata(nodata) if nodata is not None else classes


def open_clusters(path, chunks=None, band: int = 1, *, like: xr.DataArray | None = None,
                  names: tuple[str, str] = ("image", "cluster layer")) -> xr.DataArray:
    """Open band ``band`` of a cluster layer (y, x) lazily: integer ids of the units whose pixels
    share their errors (a composite's day-of-year band, a flight-line id), with its nodata; with
    ``like`` (the image), checked on its grid (:func:`brdfcorr.io.grid.check_same_grid`, the two
    named ``names`` in its message)."""
    layer = open_raster(path, "cluster layer", chunk_spec(chunks), masked=False)
    count = layer.sizes[layer.dims[0]]
    if not 1 <= band <= count:
        raise InputError(f"cluster layer {path} has {count} band(s); band {band} does not exist")
    if layer.dtype.kind not in "iu":
        raise InputError(f"cluster layer {path} has data type {layer.dtype}; it needs integer ids "
                         "(a day-of-year band, a flight-line id)")
    nodata = layer.rio.nodata
    layer = layer.isel({layer.dims[0]: band - 1}, drop=True)
    layer.name = "clusters"
    layer = layer.rio.write_nodata(nodata) if nodata is not None else layer
    if like is not None:
        check_same_grid({names[0]: like, names[1]: layer})
    return layer
