"""The one grid check: are two rasters on the same grid (shape, CRS, transform)?

Every layer a correction reads (angles, class map, slope and aspect, an obs file, a corrected image
beside its input) must lie on the image's grid pixel for pixel. :func:`grid_difference` says how two
layers' grids differ, with one tolerance (:data:`TOLERANCE`); :func:`check_same_grid` turns a
difference into the one error, :class:`~brdfcorr.errors.GridMismatchError`, naming both layers
and what differs.

A layer that carries no georeference at all (a bare array: no CRS and no x/y coordinates) has no
grid to contradict the image's; it is on the grid when its shape is.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr

from brdfcorr.errors import GridMismatchError, InputError

__all__ = ["TOLERANCE", "grid_difference", "check_same_grid", "describe_layer", "refuse_gcps"]

#: Largest difference between two transforms' coefficients that still means the same grid, as a
#: fraction of the pixel size [-]: far below any real misregistration, far above rounding.
TOLERANCE = 1e-6


class _Grid(NamedTuple):
    """What the grid check compares of a layer, read once per check (rioxarray works the
    transform out from the coordinates at each call)."""

    shape: tuple[int, int]  # rows, columns
    crs: object  # None without one
    transform: tuple[float, ...] | None  # the six coefficients; None without any georeference
    coords: tuple[np.ndarray | None, np.ndarray | None]  # the row and column coordinates, where it has them


def _grid(layer: xr.DataArray) -> _Grid:
    crs = layer.rio.crs
    spatial = layer.dims[-2:]
    georeferenced = crs is not None or any(dim in layer.coords for dim in spatial)
    coords = tuple(np.asarray(layer.coords[dim].values) if dim in layer.coords else None for dim in spatial)
    return _Grid(tuple(layer.shape[-2:]), crs,  # type: ignore[arg-type]
                 tuple(layer.rio.transform())[:6] if georeferenced else None, coords)  # type: ignore[arg-type]


def grid_difference(layer: xr.DataArray, base: xr.DataArray) -> str | None:
    """How ``layer``'s grid differs from ``base``'s, or None when they are the same grid.

    Compared on the last two dims: the shape (rows, columns), then the CRS (where both have one: a
    layer without a CRS has none to contradict the other's, e.g. angle arrays built on the image's
    x/y coordinates), then the transforms, coefficient by coefficient within :data:`TOLERANCE` of
    ``base``'s pixel size, then the row and column coordinates where both have them, each within
    the same tolerance (rioxarray works a transform out from the first two coordinates only: two
    layers cut from one grid with different rows left out have the same transform). A layer
    without any georeference (module docstring) is compared by its shape only.
    """
    return _difference(_grid(layer), _grid(base))


def _difference(grid: _Grid, base: _Grid) -> str | None:
    if grid.shape != base.shape:
        return f"shape (rows, columns) {grid.shape} differs from {base.shape}"
    if grid.transform is None or base.transform is None:
        return None
    if grid.crs is not None and base.crs is not None and grid.crs != base.crs:
        return f"CRS {grid.crs} differs from {base.crs}"
    pixel = max(abs(base.transform[0]), abs(base.transform[4]), 1e-12)
    for axis, sort, mine, theirs in zip(("rows", "columns"), ("'y', ascending=False", "'x'"), grid.coords,
                                        base.coords):
        if len(mine if mine is not None else ()) > 1 and _apart(mine, theirs, TOLERANCE * pixel) is not None \
                and _apart(mine[::-1], theirs, TOLERANCE * pixel) is None:  # type: ignore[index]
            return (f"its {axis} run the other way (coordinates ascending in one, descending in the other): "
                    f"sort both alike, e.g. layer.sortby({sort}): north up, west to east")
    if not np.allclose(grid.transform, base.transform, rtol=0, atol=TOLERANCE * pixel):
        return f"transform {grid.transform} differs from {base.transform}"
    for axis, mine, theirs in zip(("row", "column"), grid.coords, base.coords):
        apart = _apart(mine, theirs, TOLERANCE * pixel)
        if apart is not None:
            return (f"its {axis} coordinates differ from position {apart} on ({mine[apart]} against "  # type: ignore[index]
                    f"{theirs[apart]}; the transforms agree, the layers are paired pixel by pixel)")  # type: ignore[index]
    return None


def _apart(mine: np.ndarray | None, theirs: np.ndarray | None, tolerance: float) -> int | None:
    """The first position where two coordinate arrays differ by more than ``tolerance`` (by
    equality where they are not numbers), or None (also where either is missing)."""
    if mine is None or theirs is None:
        return None
    if mine.dtype.kind in "iuf" and theirs.dtype.kind in "iuf":
        different = ~np.isclose(mine, theirs, rtol=0, atol=tolerance)
    else:
        different = mine != theirs
    return int(np.argmax(different)) if np.any(different) else None


def describe_layer(name: str, layer: xr.DataArray) -> str:
    """A layer's name for messages, with its file where it has one: ``classes (classes.tif)``; the
    encoding's ``label`` over its ``source`` (a product folder for the scratch raster that stacks
    its bands, :attr:`brdfcorr.io.scene.SceneSources.label`)."""
    source = layer.encoding.get("label") or layer.encoding.get("source")
    return f"{name} ({source})" if source else name


def _check_finite_transform(name: str, layer: xr.DataArray, grid: _Grid) -> None:
    """A georeferenced layer whose transform holds NaN or inf has no grid at all: say so (it was
    reported as "not on the grid" of the image)."""
    if grid.transform is None or (grid.crs is None and not all(dim in layer.coords for dim in layer.dims[-2:])):
        return
    if not np.all(np.isfinite(grid.transform)):
        shown = ", ".join(f"{value:g}" for value in grid.transform)
        raise InputError(f"{describe_layer(name, layer)}: its geotransform ({shown}) holds non-finite values")


def check_same_grid(layers: Mapping[str, xr.DataArray], reference: str | None = None) -> None:
    """Raise :class:`GridMismatchError` unless all layers are on one grid (:func:`grid_difference`).

    Parameters
    ----------
    layers : mapping of str to DataArray
        Named layers (``{"image": ..., "classes": ...}``), compared on their last two dims.
    reference : str, optional
        The layer the others are compared with (default: the first).

    Raises
    ------
    GridMismatchError
        ``{name} ({file}) is not on the grid of {reference} ({file}): {what differs}``.
    InputError
        A layer whose geotransform holds NaN or inf.
    """
    reference = reference or next(iter(layers))
    grids = {name: _grid(layer) for name, layer in layers.items()}
    for name, layer in layers.items():
        _check_finite_transform(name, layer, grids[name])
    for name, layer in layers.items():
        difference = None if name == reference else _difference(grids[name], grids[reference])
        if difference is not None:
            where = describe_layer(reference, layers[reference])
            raise GridMismatchError(f"{describe_layer(name, layer)} is not on the grid of {where}: {difference}")


def refuse_gcps(layer: xr.DataArray, name: str, needs: str, instead: str) -> None:
    """An :class:`InputError` where ``layer`` is georeferenced by ground control points (GCPs)
    instead of a geotransform: rioxarray gives it the GCPs' CRS and an identity transform (a pixel
    of 1 by 1 in the CRS's unit, row 0 at the CRS's origin), which locates nothing. ``needs`` says
    what the transform was wanted for, ``instead`` what to do (besides warping the file); ``name``
    begins the message (:func:`describe_layer` names its file)."""
    if layer.rio.get_gcps():
        raise InputError(f"{name} is georeferenced by ground control points, not a geotransform, and {needs} "
                         f"needs one: warp it onto a grid first (gdalwarp -of GTiff IN OUT), or {instead}")
