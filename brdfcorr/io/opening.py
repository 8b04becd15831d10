"""Opening rasters with one error for every reader: a missing or unreadable file, or one GDAL
reads only as subdatasets, is an :class:`~brdfcorr.errors.InputError` naming the file and its role
("image", "class map", "DEM")."""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import rasterio
import rioxarray
import xarray as xr

from brdfcorr.errors import InputError
from brdfcorr.io.sensors.products import hdf5_hint
from brdfcorr.io.writer import DEFAULT_CHUNK

__all__ = ["open_raster", "open_layer", "opened", "chunk_spec"]


def open_raster(path, role: str, chunks, masked: bool, mask_and_scale: bool = False) -> xr.DataArray:
    """A raster (band, y, x) as rioxarray opens it, lazily, read without a lock; ``source`` in its encoding."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"{role} file {path} does not exist")
    try:
        with warnings.catch_warnings():
            # Per-band scales/offsets: rioxarray applies each band's, and says so in a warning.
            warnings.filterwarnings("ignore", r"(Scales|Offsets) differ across bands", UserWarning)
            # lock=False: every dask thread reads through its own handle, so reads run in parallel.
            array = rioxarray.open_rasterio(path, chunks=chunks, masked=masked, mask_and_scale=mask_and_scale,
                                            lock=False)
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}{hdf5_hint(path)}") from None
    if isinstance(array, list):  # subdatasets: not a plain raster
        raise InputError(f"{role} file {path} holds several subdatasets; give one raster{hdf5_hint(path)}")
    array.encoding["source"] = str(path)
    return array


def open_layer(path, role: str, chunks=None) -> xr.DataArray:
    """Any raster (band, y, x), lazily, nodata as NaN; ``role`` names it in errors ("DEM")."""
    return open_raster(path, role, chunk_spec(chunks), masked=True)


@contextlib.contextmanager
def opened(path, role: str):
    """The rasterio dataset of ``path``; an unreadable file is an InputError naming ``role``."""
    try:
        with rasterio.open(path) as dataset:
            yield dataset
    except rasterio.errors.RasterioError as error:
        raise InputError(f"cannot read {role} file {path}: {error}") from None


def chunk_spec(chunks):
    """Dask chunks of a (band, y, x) raster: an int is the spatial chunk size, all bands in one chunk."""
    if chunks is None:
        chunks = DEFAULT_CHUNK
    if isinstance(chunks, int):
        return {"band": -1, "y": chunks, "x": chunks}
    return chunks


