"""What the HDF5/NetCDF-4 products (NEON AOP, EMIT) share: telling such a file by its signature,
the optional h5py/h5netcdf dependency, chunk sizes and the georeference of an array read from one."""

from __future__ import annotations

from pathlib import Path

import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine

from brdfcorr.errors import InputError
from brdfcorr.io.sensors.grids import grid_template
from brdfcorr.io.writer import DEFAULT_CHUNK

__all__ = ["HDF5_SIGNATURE", "is_hdf5", "require_hdf5", "spatial_chunks", "on_grid"]

#: The 8 bytes an HDF5 file (and so a NetCDF-4 file) starts with.
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"

_INSTALL_HINT = "reading it needs h5py and h5netcdf: pip install 'brdfcorr[hdf5]'"


def is_hdf5(path: str | Path) -> bool:
    """True if the file starts with the HDF5 signature (HDF5 and NetCDF-4 files)."""
    try:
        with open(path, "rb") as stream:
            return stream.read(8) == HDF5_SIGNATURE
    except OSError:
        return False


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
