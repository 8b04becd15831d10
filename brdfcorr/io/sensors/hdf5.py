"""What the HDF5/NetCDF-4 products (NEON AOP, EMIT) share: telling such a file by its signature,
the optional h5py/h5netcdf dependency, chunk sizes and the georeference of an array read from one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine

from brdfcorr.errors import InputError, SensorInputError
from brdfcorr.io.sensors.grids import grid_template
from brdfcorr.io.writer import DEFAULT_CHUNK

__all__ = ["HDF5_SIGNATURE", "METADATA_LIMIT", "is_hdf5", "require_hdf5", "spatial_chunks", "on_grid",
           "read_small", "as_number", "check_transform", "hdf5_open_failure"]

#: The 8 bytes an HDF5 file (and so a NetCDF-4 file) starts with.
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

#: Most entries a metadata item (wavelengths, a map info, a log value, a GLT is not one) may declare:
#: NEON's and EMIT's have at most a few hundred. A larger one is refused before it is read (an item
#: declared with 2e9 entries was read whole: a MemoryError).
METADATA_LIMIT = 100_000

_INSTALL_HINT = "reading it needs h5py and h5netcdf: pip install 'brdfcorr[hdf5]'"


def is_hdf5(path: str | Path) -> bool:
    """True if the file starts with the HDF5 signature (HDF5 and NetCDF-4 files)."""
    try:
        with open(path, "rb") as stream:
            return stream.read(8) == HDF5_SIGNATURE
    except OSError:
        return False


def hdf5_open_failure(path: str | Path) -> str | None:
    """Why HDF5 cannot open ``path`` (a truncated or damaged file with the HDF5 signature), or None
    where it can, where the file is no HDF5 file or h5py is not installed. Asked before GDAL opens
    such a file: GDAL's own HDF5 library prints tens of ``HDF5-DIAG`` lines on stderr first."""
    if not is_hdf5(path):
        return None
    try:
        h5py = require_hdf5(path)
    except InputError:
        return None
    try:
        h5py.File(path, "r").close()
    except OSError as error:
        return str(error)
    return None


def require_hdf5(path: str | Path):
    """The h5py module, or :class:`InputError` naming the file and the extra to install.

    h5netcdf (xarray's engine for the lazy reads) is checked too.
    """
    try:
        import h5netcdf  # noqa: F401
        import h5py
    except ImportError:
        raise InputError(f"{path} is an HDF5/NetCDF-4 product; {_INSTALL_HINT}") from None
    return h5py


def spatial_chunks(chunks, like: xr.DataArray | None = None) -> tuple:
    """(y, x) chunks from an int, a dict with "y"/"x" (its values as dask takes them), or None:
    ``like``'s chunk sizes [pixels] where it is chunked, else :data:`brdfcorr.io.writer.DEFAULT_CHUNK`."""
    if chunks is None and like is not None and like.chunks:
        return int(max(like.chunksizes["y"])), int(max(like.chunksizes["x"]))
    if chunks is None:
        return DEFAULT_CHUNK, DEFAULT_CHUNK
    if isinstance(chunks, int):
        return chunks, chunks
    return chunks.get("y", DEFAULT_CHUNK), chunks.get("x", DEFAULT_CHUNK)


def on_grid(array: xr.DataArray, transform: Affine, crs) -> xr.DataArray:
    """``array`` (..., y, x) with pixel-centre ``y``/``x`` coords, CRS (where not None) and transform."""
    template = grid_template(transform, (array.sizes["y"], array.sizes["x"]), None)
    array = array.assign_coords(y=template["y"].values, x=template["x"].values)
    if crs is not None:
        array = array.rio.write_crs(crs)
    return array.rio.write_transform(transform)


def read_small(dataset, source: str, limit: int = METADATA_LIMIT) -> np.ndarray:
    """The values of a small HDF5 dataset (metadata) as an array, refused unread when it declares
    more than ``limit`` entries; ``source`` names it in errors (``FILE: Metadata/...``)."""
    size = int(np.prod(dataset.shape, dtype=np.float64)) if dataset.shape is not None else 0
    if size > limit:
        raise SensorInputError(f"{source} declares {size} entries {tuple(dataset.shape)}; a metadata item "
                               f"has at most {limit}")
    try:
        return np.asarray(dataset[()])
    except (OSError, TypeError, ValueError) as error:
        raise SensorInputError(f"{source}: cannot read it ({error})") from None


def as_number(value, source: str) -> float:
    """One real number from an HDF5 attribute or scalar dataset (a number, a one-element array, a
    numeric string); NaN and inf are returned as they are, for the caller to judge.

    Raises
    ------
    SensorInputError
        Several values, text that is no number, a complex number (its imaginary part would be lost).
    """
    array = np.asarray(value)
    if array.size != 1:
        raise SensorInputError(f"{source}: {array.size} values {tuple(array.shape)} where one number is expected")
    item = array.ravel()[0]
    if isinstance(item, (complex, np.complexfloating)):
        raise SensorInputError(f"{source}: {item!r} is a complex number; a real one is expected")
    if isinstance(item, bytes):
        item = item.decode("utf-8", "replace")
    try:
        return float(item)
    except (TypeError, ValueError):
        raise SensorInputError(f"{source}: {str(item)[:80]!r} is no number") from None


def check_transform(values, source: str) -> None:
    """Refuse a geotransform (6 GDAL-order or affine coefficients) that holds NaN or inf: every
    pixel's position would be undefined (it was reported as "not on the grid")."""
    bad = [value for value in values if not math.isfinite(value)]
    if bad:
        shown = ", ".join(f"{value:g}" for value in values)
        raise SensorInputError(f"{source}: the geotransform ({shown}) holds non-finite values")
