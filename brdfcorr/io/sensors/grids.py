"""Bring coarse angle grids onto an image grid, lazily.

Sensor products deliver their angles on grids much coarser than the image (Sentinel-2: 5 km nodes;
Landsat angle rasters resampled by third parties; any angle raster in another CRS). The functions
here build a dask-backed array on the image grid whose blocks are interpolated, one at a time, from
the small coarse grid held in memory: the full-resolution angles are never materialized at once.

Interpolation is bilinear between the coarse *pixel centres*, with the edge value held constant
beyond the outermost centres (half a coarse pixel). Where both grids share the CRS and neither is
rotated (Sentinel-2 angle grids on their tile's image), rows and columns map to coarse positions
independently and a block is two 1-D linear interpolations (the bilinear weights are products of
1-D weights). Otherwise each block's pixel centres are transformed into the coarse grid's CRS with
pyproj and looked up with ``scipy.ndimage.map_coordinates`` (``order=1``). Azimuths are
interpolated through their sine and cosine and recombined with ``arctan2``, so that 359 deg and
1 deg average to 0 deg, never to 180 deg.

A view direction whose zenith passes near 0 (a push-broom sensor's nadir line) is interpolated as
one vector (:data:`VIEW_KINDS`): the ground-projected view vector (tan θ sin φ, tan θ cos φ)
(:func:`view_vector`; for a sensor at height H above a flat ground it is the horizontal offset from
the pixel to the sensor over H, linear in the pixel's position), its two components as ordinary
grids, and the zenith and azimuth taken from the interpolated vector (:func:`view_angles`). Across
the nadir line the azimuth turns by 180 deg within a few kilometres and the zenith has a kink at its
minimum near 0; interpolated apart, the zenith is about 0.2 deg and the azimuth up to 99 deg off
there (``tests/io/sensors/test_sensors_sentinel2.py``).

The angle check's statistics (:func:`brdfcorr.io.angles.check_angles`) of a separable grid come
from the coarse grid (:func:`grid_statistics`): the pixels are interpolated once, when corrected.
"""

from __future__ import annotations

from typing import Literal

import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine
from pyproj import Transformer
from scipy import ndimage

from brdfcorr.errors import SensorInputError

__all__ = ["GRID_SOURCE", "GRID_STATISTICS", "VIEW_KINDS", "check_covers", "coarse_positions", "grid_nodes",
           "grid_statistics", "grid_window", "grid_template", "interpolate_at", "interpolate_window", "pixel_centres",
           "to_grid", "view_angles", "view_vector", "wrap_azimuth"]

#: Encoding key of a layer interpolated by :func:`to_grid` holding its shape (y, x) and the statistics
#: of :func:`brdfcorr.io.angles.check_angles` (min, max, finite count, count in [0, 90) and their
#: sum) from the coarse grid (:func:`grid_statistics`), which the check takes instead of a pass.
GRID_STATISTICS = "brdfcorr_grid_statistics"
#: Encoding key of a separable :func:`to_grid` output: its coarse grid and transforms, so that
#: :func:`grid_window` interpolates a few pixels without computing a whole chunk.
GRID_SOURCE = "brdfcorr_grid_source"
#: Chunk size [pixels] of angle grids interpolated onto an image grid (a cheap computation: large chunks).
GRID_CHUNK = 2048
#: Interpolation kinds (the ``angle`` of :func:`to_grid`) of a view direction given as its
#: ground-projected vector (2, y, x) (:func:`view_vector`): the zenith or the azimuth [deg] of the
#: vector interpolated component by component.
VIEW_KINDS = ("view_zenith", "view_azimuth")
#: How a coarse grid is interpolated: False linear, True an azimuth [deg] through its sine and
#: cosine, or one of :data:`VIEW_KINDS`.
Kind = bool | Literal["view_zenith", "view_azimuth"]


def wrap_azimuth(azimuth):
    """Azimuth [deg] wrapped into [0, 360); numpy, dask and xarray input, lazily."""
    wrapped = azimuth % 360.0
    # A tiny negative azimuth wraps to 360 - 1e-15, which rounds to 360.0: map it back to 0.
    return wrapped - 360.0 * (wrapped >= 360.0)


def view_vector(zenith, azimuth) -> np.ndarray:
    """The ground-projected view vector (tan θ sin φ, tan θ cos φ) [-] of view zeniths θ and
    azimuths φ [deg] (numpy arrays), stacked on a new first axis (east, north): the horizontal
    offset from the pixel to the sensor per unit of its height over a flat ground. Its
    components vary smoothly where the azimuth turns by 180 deg (the nadir line); NaN stays NaN.
    The zenith must lie in [0, 90)."""
    radians = np.radians(np.asarray(azimuth, dtype=np.float64))
    slope = np.tan(np.radians(np.asarray(zenith, dtype=np.float64)))
    return np.stack([slope * np.sin(radians), slope * np.cos(radians)])


def view_angles(vector) -> tuple[np.ndarray, np.ndarray]:
    """Zenith [deg, in [0, 90)] and azimuth [deg, in [0, 360)] of ground-projected view vectors
    (2, ...) (:func:`view_vector`); the azimuth of a zero vector (the nadir) is 0."""
    east, north = vector[0], vector[1]
    zenith = np.degrees(np.arctan(np.hypot(east, north)))
    return zenith, wrap_azimuth(np.degrees(np.arctan2(east, north)))


def _from_vector(vector: np.ndarray, kind: Kind) -> np.ndarray:
    """The zenith (``"view_zenith"``) or azimuth (``"view_azimuth"``) [deg] of view vectors (2, ...)."""
    return view_angles(vector)[0 if kind == "view_zenith" else 1]


def grid_nodes(values: np.ndarray, angle: Kind) -> np.ndarray:
    """The angles [deg] (y, x) at the nodes of a coarse grid as :func:`to_grid` records it
    (:data:`GRID_SOURCE`): the values themselves, or those of the view vector for :data:`VIEW_KINDS`."""
    return _from_vector(values, angle) if angle in VIEW_KINDS else values


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


def _axis_aligned(transform: Affine) -> bool:
    """Whether a transform has no rotation or shear (rows along y, columns along x)."""
    return transform.b == 0.0 and transform.d == 0.0


def _grid_of(array: xr.DataArray, role: str):
    """(transform, crs, shape) of a (y, x) DataArray; a clear error when it has no grid."""
    if array.ndim != 2 or set(array.dims) != {"y", "x"}:
        raise SensorInputError(f"{role} must have the dimensions (y, x), got {array.dims}")
    try:
        transform = array.rio.transform(recalc=False)
    except Exception as error:  # rioxarray raises several kinds for missing/irregular coords
        raise SensorInputError(f"{role} has no usable affine transform: {error}") from error
    return transform, array.rio.crs, (array.sizes["y"], array.sizes["x"])


def _axis_weights(positions: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear interpolation along one axis between the centres of ``size`` coarse cells:
    ``positions`` in coarse cell indices (centre of cell k at k); the lower and upper neighbour
    indices and the weight of the upper one. Beyond the outermost centres both neighbours are the
    edge cell (the edge value held, as ``map_coordinates(mode="nearest")`` does)."""
    clamped = np.clip(positions, 0.0, size - 1.0)
    lower = np.minimum(np.floor(clamped).astype(np.intp), size - 1)
    upper = np.minimum(lower + 1, size - 1)
    return lower, upper, clamped - lower


def _weight_matrix(positions: np.ndarray, size: int) -> np.ndarray:
    """(len(positions), size) matrix of the 1-D linear interpolation weights (:func:`_axis_weights`)."""
    lower, upper, t = _axis_weights(positions, size)
    weights = np.zeros((positions.size, size))
    np.add.at(weights, (np.arange(positions.size), lower), 1.0 - t)
    np.add.at(weights, (np.arange(positions.size), upper), t)
    return weights


def _separable(values: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``values`` (..., y, x) at the grid of coarse positions ``rows`` x
    ``cols`` (an axis-aligned target grid) as ``R @ values @ C.T``, R and C the 1-D linear interpolation
    weights along rows and columns (the bilinear weights are their products). Finite ``values``
    only: a product with a NaN node is NaN along its whole row and column."""
    return _weight_matrix(rows, values.shape[-2]) @ values @ _weight_matrix(cols, values.shape[-1]).T


def coarse_positions(source_transform: Affine, target_transform: Affine, rows: np.ndarray, cols: np.ndarray):
    """Positions, in coarse cell indices (centre of cell k at k), of the centres of the target
    pixel rows ``rows`` and columns ``cols`` (axis-aligned grids of one CRS)."""
    x = target_transform.c + target_transform.a * (cols + 0.5)
    y = target_transform.f + target_transform.e * (rows + 0.5)
    return (y - source_transform.f) / source_transform.e - 0.5, (x - source_transform.c) / source_transform.a - 0.5


def interpolate_at(values: np.ndarray, rows: np.ndarray, cols: np.ndarray, angle: Kind) -> np.ndarray:
    """Bilinear interpolation of finite coarse ``values`` (..., y, x) at the grid of coarse
    positions ``rows`` x ``cols`` (:func:`coarse_positions`; the edge value held beyond the
    outermost centres), as the separable path of :func:`to_grid` interpolates every pixel
    (:func:`_separable`); azimuths [deg] with ``angle`` True, through their sine and cosine; the
    zenith or azimuth [deg] of view vectors (2, y, x) with ``angle`` in :data:`VIEW_KINDS`."""
    if angle in VIEW_KINDS:
        return _from_vector(_separable(values, rows, cols), angle)
    if not angle:
        return _separable(values, rows, cols)
    radians = np.radians(values)
    azimuth = np.degrees(np.arctan2(_separable(np.sin(radians), rows, cols), _separable(np.cos(radians), rows, cols)))
    # arctan2 gives (-180, 180]: wrap_azimuth's x % 360 is x + 360 below 0 (in place, no modulo).
    np.add(azimuth, 360.0, out=azimuth, where=azimuth < 0.0)
    azimuth[azimuth >= 360.0] = 0.0  # -1e-15 + 360 rounds to 360
    return azimuth


def _interpolate_block(block_info, *, values, source_transform, target_transform, transformer,
                       angle: Kind, separable: bool = False):
    """Interpolate the in-memory coarse ``values`` at the pixel centres of one output block."""
    info = block_info[None]
    (row0, row1), (col0, col1) = info["array-location"]
    if separable:
        # Rows and columns map to coarse positions independently: two 1-D interpolations per
        # block instead of a four-neighbour lookup per pixel (the same bilinear values).
        rows, cols = coarse_positions(source_transform, target_transform, np.arange(row0, row1),
                                       np.arange(col0, col1))
        return interpolate_at(values, rows, cols, angle)
    x, y = pixel_centres(target_transform, row0, col0, (row1 - row0, col1 - col0))
    if transformer is not None:
        x, y = transformer.transform(x, y)
    col, row = ~source_transform @ (x, y)
    # map_coordinates indexes pixel centres at integer positions; (col, row) count from corners.
    coordinates = np.stack([row - 0.5, col - 0.5])
    if angle in VIEW_KINDS:
        vector = np.stack([ndimage.map_coordinates(component, coordinates, order=1, mode="nearest")
                           for component in values])
        return _from_vector(vector, angle)
    if not angle:
        return ndimage.map_coordinates(values, coordinates, order=1, mode="nearest")
    radians = np.radians(values)
    sine = ndimage.map_coordinates(np.sin(radians), coordinates, order=1, mode="nearest")
    cosine = ndimage.map_coordinates(np.cos(radians), coordinates, order=1, mode="nearest")
    return wrap_azimuth(np.degrees(np.arctan2(sine, cosine)))


def _breakpoints(positions: np.ndarray, size: int) -> np.ndarray:
    """Indices of the first and last pixel between each pair of neighbouring coarse centres (and
    in each clamped edge zone): along one axis the interpolant is linear between them."""
    piece = np.clip(np.floor(positions), -1, size - 1)  # -1 before the first centre, size - 1 after the last
    change = np.flatnonzero(np.diff(piece)) + 1
    return np.unique(np.concatenate([[0, positions.size - 1], change, change - 1]))


def grid_statistics(values: np.ndarray, source_transform: Affine, target_transform: Affine,
                    shape: tuple[int, int], angle: Kind) -> tuple[float, float, float, float, float] | None:
    """The statistics of :func:`brdfcorr.io.angles.check_angles` of the interpolated grid, from
    the coarse grid alone (no pass over the pixels): min, max, finite count, count in [0, 90) and
    the sum of the values in [0, 90).

    Along each axis the interpolant is linear between the pixels next to the coarse centres
    (:func:`_breakpoints`), so a zenith's min and max over every pixel are those over the grid of
    these rows and columns, and its sum is ``(1' R) values (C' 1)`` (R, C the interpolation
    weights): exact. For an azimuth (sine and cosine interpolated) they are those of that grid
    (the directions at the corners of each coarse cell's pixels), which the unit check needs; so
    are those of a view vector's zenith and azimuth (:data:`VIEW_KINDS`: not linear between the
    nodes, their sum is that grid's mean times the pixel count).
    None where the grids are not separable (:func:`to_grid`) or a zenith leaves [0, 90) (a pass
    over the pixels counts those).
    """
    rows, cols = coarse_positions(source_transform, target_transform, np.arange(shape[0]), np.arange(shape[1]))
    sample = interpolate_at(values, rows[_breakpoints(rows, values.shape[-2])],
                                    cols[_breakpoints(cols, values.shape[-1])], angle)
    count = float(shape[0] * shape[1])
    if angle:  # an azimuth, or a view vector's zenith (in [0, 90) by construction) or azimuth
        in_domain = sample[(sample >= 0) & (sample < 90)]
        return float(sample.min()), float(sample.max()), count, count * in_domain.size / sample.size, \
            count * (in_domain.mean() if in_domain.size else 0.0)
    low, high = float(sample.min()), float(sample.max())
    if not (0.0 <= low and high < 90.0):
        return None
    row_weights, col_weights = (_weight_matrix(p, n).sum(axis=0) for p, n in zip((rows, cols), values.shape[-2:]))
    total = row_weights @ values @ col_weights
    return low, high, count, count, float(total)


def _footprint(transform: Affine, shape: tuple[int, int]) -> tuple[float, float, float, float]:
    """(left, bottom, right, top) of a grid's pixels, through its four corners (rotation allowed)."""
    rows, cols = shape
    xs, ys = transform * (np.array([0, cols, cols, 0]), np.array([0, 0, rows, rows]))
    return float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max())


def check_covers(source_transform: Affine, source_shape: tuple[int, int], target_transform: Affine,
                 target_shape: tuple[int, int], transformer: Transformer | None = None,
                 source: str = "the coarse grid", margin: float = 1.0) -> None:
    """Refuse an image grid that reaches beyond a coarse grid by more than ``margin`` coarse pixels.

    :func:`to_grid` holds the edge value constant beyond the outermost pixel centres: an image
    that lies elsewhere (a tile's metadata with a wrong corner, another tile's, another CRS) would
    get the edge's angles at any distance, silently. One coarse pixel of margin keeps images on the
    tile's edge. ``transformer`` maps the image's CRS to the coarse grid's. A quality mask, which
    must cover every pixel, takes ``margin=0.5`` (the rounding of grids that agree).

    Raises
    ------
    SensorInputError
        Naming ``source``, both extents and the distance [coarse grid CRS units].
    """
    left, bottom, right, top = _footprint(target_transform, target_shape)
    if transformer is not None:
        left, bottom, right, top = transformer.transform_bounds(left, bottom, right, top, densify_pts=21)
    west, south, east, north = _footprint(source_transform, source_shape)
    pad_x = margin * (abs(source_transform.a) + abs(source_transform.b))
    pad_y = margin * (abs(source_transform.d) + abs(source_transform.e))
    beyond = max(west - left - pad_x, right - east - pad_x, south - bottom - pad_y, top - north - pad_y)
    if not beyond <= 0:  # NaN or inf (a point the CRS cannot map) is outside too
        raise SensorInputError(
            f"{source} ({west:.6g}, {south:.6g}) to ({east:.6g}, {north:.6g}) does not cover the image "
            f"({left:.6g}, {bottom:.6g}) to ({right:.6g}, {top:.6g}): it reaches {beyond:.6g} beyond, more than "
            f"{margin:g} grid step; is it the image's own (its corner, its CRS)?")


def to_grid(coarse: xr.DataArray, like: xr.DataArray, *, angle: Kind = False, chunks=None,
            name: str | None = None, attrs: dict | None = None, source: str = "the coarse grid") -> xr.DataArray:
    """Interpolate a coarse (y, x) grid onto the grid of ``like``, lazily.

    Parameters
    ----------
    coarse : xarray.DataArray
        Coarse grid (y, x) with a rioxarray transform (pixel centres are the sample positions) and,
        when ``like`` has another CRS, a CRS. Small: it is loaded into memory once. For
        :data:`VIEW_KINDS` (..., y, x) with a leading dimension of two: the ground-projected view
        vector (:func:`view_vector`).
    like : xarray.DataArray
        Image or template whose (y, x) grid the output takes (extra dims such as ``band`` are
        ignored; its data are never read).
    angle : bool or {"view_zenith", "view_azimuth"}
        True for azimuths [deg]: interpolate sin and cos and recombine, result in [0, 360).
        ``"view_zenith"`` or ``"view_azimuth"``: interpolate the two components of the view vector
        ``coarse`` as ordinary grids and give the vector's zenith [deg, in [0, 90)] or azimuth [deg,
        in [0, 360)] (:func:`view_angles`).
    chunks : int or tuple, optional
        Output chunks; default: ``like``'s (y, x) chunks if it is dask-backed, else 2048.
    name, attrs :
        Name and attrs of the output (``attrs`` replaces ``coarse``'s; units must be set here).
    source : str
        What the coarse grid is, in messages (a file and layer).

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
    vector = angle in VIEW_KINDS
    if vector and (coarse.ndim != 3 or coarse.shape[0] != 2):
        raise SensorInputError(f"{source}: a view vector grid has dimensions (2, y, x), got {coarse.dims} "
                               f"{coarse.shape}")
    coarse = coarse.transpose(..., "y", "x")
    first = coarse[0] if vector else coarse
    source_transform, source_crs, _ = _grid_of(first, "the coarse grid")
    transformer = None
    if target_crs is not None and source_crs is not None and target_crs != source_crs:
        transformer = Transformer.from_crs(target_crs, source_crs, always_xy=True)
    elif (target_crs is None) != (source_crs is None):
        raise SensorInputError(
            "cannot place the coarse grid on the image grid: only one of them has a CRS "
            f"(coarse: {source_crs}, image: {target_crs})"
        )
    values = np.asarray(coarse.values, dtype="float64")
    check_covers(source_transform, values.shape[-2:], target_transform, shape, transformer, source)
    if chunks is None:
        chunks = plane.data.chunks if isinstance(plane.data, da.Array) else GRID_CHUNK
    template = da.empty(shape, dtype="float64", chunks=chunks)
    separable = (transformer is None and _axis_aligned(source_transform) and _axis_aligned(target_transform)
                 and bool(np.isfinite(values).all()))
    data = da.map_blocks(
        _interpolate_block, dtype="float64", chunks=template.chunks, meta=np.empty((0, 0)),
        values=values, source_transform=source_transform, target_transform=target_transform,
        transformer=transformer, angle=angle, separable=separable,
    )
    result = xr.DataArray(data, dims=("y", "x"), coords={"y": plane["y"], "x": plane["x"]}, name=name,
                          attrs=dict(attrs or {}))
    if separable:  # the statistics of the angle check, from the coarse grid (no pass)
        result.encoding[GRID_SOURCE] = (shape, values, source_transform, target_transform, angle)
        statistics = grid_statistics(values, source_transform, target_transform, shape, angle)
        if statistics is not None:
            result.encoding[GRID_STATISTICS] = (*shape, *statistics)
    if target_crs is not None:
        result = result.rio.write_crs(target_crs)
    return result.rio.write_transform(target_transform)


def grid_window(layer: xr.DataArray, rows: slice, cols: slice) -> np.ndarray | None:
    """The pixels ``rows`` x ``cols`` (slices with start and stop) of a separable :func:`to_grid`
    output interpolated from its coarse grid alone (:data:`GRID_SOURCE`; the same bilinear values
    as the whole chunk's, without computing it); None where the layer has no such record or no
    longer the shape it was made for."""
    recorded = layer.encoding.get(GRID_SOURCE)
    if recorded is None or tuple(recorded[0]) != (layer.sizes.get("y"), layer.sizes.get("x")):
        return None
    _, values, source_transform, target_transform, angle = recorded
    return interpolate_window(values, source_transform, target_transform, rows, cols, angle=angle)


def interpolate_window(values: np.ndarray, source_transform: Affine, target_transform: Affine, rows: slice,
                       cols: slice, *, angle: Kind = False) -> np.ndarray:
    """Bilinear interpolation of coarse ``values`` (..., y, x), as the separable path of
    :func:`to_grid` (the coarse grid's ``source_transform`` and the target grid's, both
    axis-aligned in one CRS), at the target pixels ``rows`` x ``cols`` (slices with start and
    stop); leading dimensions of ``values`` (bands) are kept. Azimuths [deg] with ``angle`` True
    (a 2-D grid), the zenith or azimuth of view vectors (2, y, x) with ``angle`` in :data:`VIEW_KINDS`."""
    positions = coarse_positions(source_transform, target_transform, np.arange(rows.start, rows.stop),
                                  np.arange(cols.start, cols.stop))
    return interpolate_at(values, *positions, angle)
