"""Bring coarse angle grids onto an image grid, lazily.

Sensor products deliver their angles on grids much coarser than the image (Sentinel-2: 5 km nodes;
Landsat angle rasters resampled by third parties; any angle raster in another CRS). The functions
here build a dask-backed array on the image grid whose blocks are interpolated, one at a time, from
the small coarse grid held in memory: the full-resolution angles are never materialized at once.

Interpolation is bilinear between the coarse *pixel centres* (``scipy.ndimage.map_coordinates``,
``order=1``), with the edge value held constant beyond the outermost centres (half a coarse pixel).
When the image grid has another CRS, each block's pixel centres are transformed into the coarse
grid's CRS with pyproj first. Azimuths are interpolated through their sine and cosine and recombined
with ``arctan2``, so that 359 deg and 1 deg average to 0 deg, never to 180 deg.
"""

from __future__ import annotations

import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine
from pyproj import Transformer
from scipy import ndimage

from brdfcorr.errors import SensorInputError

__all__ = ["grid_template", "pixel_centres", "to_grid", "wrap_azimuth"]

#: Chunk size [pixels] of angle grids interpolated onto an image grid (a cheap computation: large chunks).
GRID_CHUNK = 2048


def wrap_azimuth(azimuth):
    """Azimuth [deg] wrapped into [0, 360); numpy, dask and xarray input, lazily."""
    wrapped = azimuth % 360.0
    # A tiny negative azimuth wraps to 360 - 1e-15, which rounds to 360.0: map it back to 0.
    return wrapped - 360.0 * (wrapped >= 360.0)


def grid_template(transform: Affine, shape: tuple[int, int], crs, chunks=GRID_CHUNK) -> xr.DataArray:
    """A lazy, all-zero (y, x) DataArray that carries an image grid (coords, CRS, transform).

    Parameters
    ----------
    transform : affine.Affine
        Pixel-corner transform of the grid (rasterio convention).
    shape : (int, int)
        Number of rows and columns.
    crs : anything rasterio/pyproj accepts, or None
    chunks : int or tuple
        Dask chunks of the template; arrays interpolated onto it inherit them.
    """
    rows, cols = shape
    x = (transform @ (np.arange(cols) + 0.5, np.full(cols, 0.5)))[0]
    y = (transform @ (np.full(rows, 0.5), np.arange(rows) + 0.5))[1]
    template = xr.DataArray(
        da.zeros(shape, dtype="float32", chunks=chunks), dims=("y", "x"), coords={"y": y, "x": x}
    )
    template = template.rio.write_transform(transform)
    if crs is not None:
        template = template.rio.write_crs(crs)
    return template


def pixel_centres(transform: Affine, row_offset: int, col_offset: int, shape: tuple[int, int]):
    """Map coordinates (x, y) of the pixel centres of one block of a grid [CRS units]."""
    rows, cols = np.meshgrid(
        np.arange(row_offset, row_offset + shape[0]) + 0.5,
        np.arange(col_offset, col_offset + shape[1]) + 0.5,
        indexing="ij",
    )
    return transform @ (cols, rows)


def _grid_of(array: xr.DataArray, role: str):
    """(transform, crs, shape) of a (y, x) DataArray; a clear error when it has no grid."""
    if array.ndim != 2 or set(array.dims) != {"y", "x"}:
        raise SensorInputError(f"{role} must have the dimensions (y, x), got {array.dims}")
    try:
        transform = array.rio.transform(recalc=False)
    except Exception as error:  # rioxarray raises several kinds for missing/irregular coords
        raise SensorInputError(f"{role} has no usable affine transform: {error}") from error
    return transform, array.rio.crs, (array.sizes["y"], array.sizes["x"])


def _interpolate_block(block_info, *, values, source_transform, target_transform, transformer,
                       angle: bool):
    """Interpolate the in-memory coarse ``values`` at the pixel centres of one output block."""
    info = block_info[None]
    (row0, row1), (col0, col1) = info["array-location"]
    x, y = pixel_centres(target_transform, row0, col0, (row1 - row0, col1 - col0))
    if transformer is not None:
        x, y = transformer.transform(x, y)
    col, row = ~source_transform @ (x, y)
    # map_coordinates indexes pixel centres at integer positions; (col, row) count from corners.
    coordinates = np.stack([row - 0.5, col - 0.5])
    if not angle:
        return ndimage.map_coordinates(values, coordinates, order=1, mode="nearest")
    radians = np.radians(values)
    sine = ndimage.map_coordinates(np.sin(radians), coordinates, order=1, mode="nearest")
    cosine = ndimage.map_coordinates(np.cos(radians), coordinates, order=1, mode="nearest")
    return wrap_azimuth(np.degrees(np.arctan2(sine, cosine)))


def to_grid(coarse: xr.DataArray, like: xr.DataArray, *, angle: bool = False, chunks=None,
            name: str | None = None, attrs: dict | None = None) -> xr.DataArray:
    """Interpolate a coarse (y, x) grid onto the grid of ``like``, lazily.

    Parameters
    ----------
    coarse : xarray.DataArray
        Coarse grid (y, x) with a rioxarray transform (pixel centres are the sample positions) and,
        when ``like`` has another CRS, a CRS. Small: it is loaded into memory once.
    like : xarray.DataArray
        Image or template whose (y, x) grid the output takes (extra dims such as ``band`` are
        ignored; its data are never read).
    angle : bool
        True for azimuths [deg]: interpolate sin and cos and recombine, result in [0, 360).
    chunks : int or tuple, optional
        Output chunks; default: ``like``'s (y, x) chunks if it is dask-backed, else 2048.
    name, attrs :
        Name and attrs of the output (``attrs`` replaces ``coarse``'s; units must be set here).

    Returns
    -------
    xarray.DataArray
        Dask-backed float64 (y, x) array on ``like``'s grid, with its coords and CRS.

    Notes
    -----
    Bilinear between coarse pixel centres, constant beyond the outermost centres; NaNs in
    ``coarse`` spread to the output pixels whose four neighbours include them (fill gaps first).
    """
    plane = like.isel({dim: 0 for dim in like.dims if dim not in ("y", "x")}).transpose("y", "x")
    target_transform, target_crs, shape = _grid_of(plane, "the image grid (like)")
    source_transform, source_crs, _ = _grid_of(coarse.transpose("y", "x"), "the coarse grid")
    transformer = None
    if target_crs is not None and source_crs is not None and target_crs != source_crs:
        transformer = Transformer.from_crs(target_crs, source_crs, always_xy=True)
    elif (target_crs is None) != (source_crs is None):
        raise SensorInputError(
            "cannot place the coarse grid on the image grid: only one of them has a CRS "
            f"(coarse: {source_crs}, image: {target_crs})"
        )
    if chunks is None:
        chunks = plane.data.chunks if isinstance(plane.data, da.Array) else GRID_CHUNK
    values = np.asarray(coarse.transpose("y", "x").values, dtype="float64")
    template = da.empty(shape, dtype="float64", chunks=chunks)
    data = da.map_blocks(
        _interpolate_block, dtype="float64", chunks=template.chunks, meta=np.empty((0, 0)),
        values=values, source_transform=source_transform, target_transform=target_transform,
        transformer=transformer, angle=angle,
    )
    result = xr.DataArray(
        data, dims=("y", "x"), coords={"y": plane["y"], "x": plane["x"]}, name=name,
        attrs=dict(attrs or {}),
    )
    if target_crs is not None:
        result = result.rio.write_crs(target_crs)
    return result.rio.write_transform(target_transform)
