"""NEON AOP and EMIT images are HDF5/NetCDF files, not rasters GDAL reads: told by content, and
opened through their readers (:mod:`.neon`, :mod:`.emit`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import xarray as xr

from brdfcorr.errors import InputError
from brdfcorr.io.sensors.hdf5 import is_hdf5, require_hdf5

__all__ = ["hdf5_product", "hdf5_hint", "open_product"]


def hdf5_product(path) -> str | None:
    """``"neon"`` or ``"emit"`` for an image that is a NEON AOP reflectance HDF5 or an EMIT L2A
    reflectance NetCDF (told by content, not by name), else None: a raster GDAL reads. Without h5py
    such a file is None too, and GDAL's error on it says what to install (:func:`_hdf5_hint`)."""
    from brdfcorr.io.sensors import emit, neon

    if not is_hdf5(path):
        return None
    try:
        require_hdf5(path)
    except InputError:
        return None
    if neon.is_neon_reflectance(path):
        return "neon"
    if emit.is_emit_reflectance(path):
        return "emit"
    return None


def hdf5_hint(path) -> str:
    """For an error on an HDF5/NetCDF-4 file while h5py or h5netcdf is missing: what to install."""
    if not is_hdf5(path):
        return ""
    try:
        require_hdf5(path)
    except InputError:
        return " (NEON AOP .h5 and EMIT .nc images need h5py and h5netcdf: pip install 'brdfcorr[hdf5]')"
    return ""


def open_product(kind: str, path, chunks, wavelengths: Sequence[float] | None, scale: float | None,
                  offset: float | None) -> xr.DataArray:
    """A NEON or EMIT image through its reader (:mod:`brdfcorr.io.sensors.neon`, ``.emit``), with
    ``wavelengths`` replacing the product's band centres where given; ``chunks`` as for the readers."""
    from brdfcorr.io.sensors import read_emit_image, read_neon_image

    reader = read_neon_image if kind == "neon" else read_emit_image
    try:
        image = reader(path, chunks=chunks, scale=scale, offset=offset)
    except OSError as error:  # an HDF5 file that h5py opened but cannot read further
        raise InputError(f"cannot read image file {path}: {error}") from None
    if wavelengths is not None:
        values = np.asarray([float(value) for value in wavelengths])
        if values.size != image.sizes["band"] or not np.all(np.isfinite(values) & (values > 0)):
            raise InputError(f"{path}: the given wavelengths must be {image.sizes['band']} finite values > 0 nm")
        image = image.assign_coords(wavelength=("band", values, {"units": "nm"}))
    return image


