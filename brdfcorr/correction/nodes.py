"""The correction factor at the nodes of a coarse angle grid, interpolated to the pixels.

A sensor that gives its angles on a coarse grid (the 5 km Sentinel-2 grids of ``MTD_TL.xml``)
is normally corrected pixel by pixel: the angles are interpolated to each pixel and the factor
f(ref) / f(obs) is evaluated there (:func:`brdfcorr.correction.normalize`). Here the factor is
evaluated once per node of the angle grid, in every band, and interpolated bilinearly to the
pixels, as sen2nbar does for Sentinel-2 (Montero et al. 2023). Per pixel only one bilinear
interpolation and one product per band remain, so the correction costs about what reading and
writing the image costs.

The factor is not linear in the angles, so the two methods differ, but since the Sentinel-2 view
direction is interpolated as a vector (:mod:`brdfcorr.io.sensors.grids`) only slightly: over the
whole real T23LLF tile (the coefficients of Roy et al. 2017; ``benchmarks/bench_nodes_error.py``)
by at most 0.003 % (view grids averaged over the bands) or 0.004 % (each band's own), 0.0001 % in
the median, with the factor interpolated everywhere (sen2nbar's method, the default). With zenith
and azimuth interpolated apart it was 0.91 % / 0.97 %, in the grid cells whose nodes' view azimuths
span more than 60 deg (the nadir line, the detector seams); ``jump`` still evaluates the factor at
each pixel of such cells (:data:`JUMP`: 0.0023 % / 0.0029 % then, for 1.5 to 4 times the time).
It suits one smooth correction over the whole image: one class, no class
map, no terrain and no uncertainty layer (``CorrectionRequest(factor_at="nodes")`` refuses the
others).

QA flags: ``nodata`` where the reflectance is not finite in some band or the interpolated factor
is not (a node without a valid geometry), ``limited`` where one of the nodes a pixel's factor
comes from was clipped to the limits.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from functools import partial

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.correction.blocks import split_pairs
from brdfcorr.correction.normalization import Normalized, normalize
from brdfcorr.correction.qa import QA, qa_attrs, set_flags
from brdfcorr.correction.reference import describe_limits, with_mean_sza
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import InputError
from brdfcorr.io.sensors.grids import GRID_SOURCE, coarse_positions, grid_nodes, interpolate_window
from brdfcorr.params import ParameterTable, ReferenceGeometry

__all__ = ["normalize_at_nodes", "node_angles", "azimuth_span", "JUMP"]

ANGLES = ("sza", "saa", "vza", "vaa")
#: A grid cell whose four nodes' view azimuths span more than this [deg] gets the factor of each
#: pixel from its own interpolated angles (module docstring): on the real T23LLF tile 11 % of the
#: pixels; the largest error left 0.11-0.15 % (``benchmarks/bench_nodes_error.py``).
JUMP = 60.0


def azimuth_span(azimuth: np.ndarray) -> np.ndarray:
    """(rows - 1, cols - 1): per cell of a grid of azimuths [deg] the largest angle between two of
    its four nodes' azimuths, each difference folded into [0, 180] [deg]."""
    corners = [azimuth[:-1, :-1], azimuth[:-1, 1:], azimuth[1:, :-1], azimuth[1:, 1:]]
    span = np.zeros(corners[0].shape)
    for index, first in enumerate(corners):
        for second in corners[index + 1:]:
            difference = np.abs(first - second) % 360.0
            span = np.maximum(span, np.minimum(difference, 360.0 - difference))
    return span


def node_angles(angles: Mapping[str, xr.DataArray]) -> dict[str, xr.DataArray]:
    """The coarse grids (y, x) the angle layers were interpolated from, with their transform and
    CRS: the nodes. Raises :class:`InputError` unless every layer was made from one coarse grid
    by :func:`brdfcorr.io.sensors.grids.to_grid` (a sensor's angle grids, not per-pixel rasters)."""
    records: dict[str, tuple] = {name: angles[name].encoding[GRID_SOURCE] for name in ANGLES
                                 if GRID_SOURCE in angles[name].encoding}
    missing = [name for name in ANGLES if name not in records]
    if missing:
        raise InputError(f"the factor at the angle grid's nodes needs angles given on a coarse grid "
                         f"(Sentinel-2 MTD_TL.xml); {', '.join(missing)} are per-pixel rasters")
    transforms = {record[2] for record in records.values()}
    shapes = {np.shape(record[1])[-2:] for record in records.values()}
    if len(transforms) != 1 or len(shapes) != 1:
        raise InputError("the factor at the angle grid's nodes needs the sun and view angles on one coarse grid")
    like = angles["sza"]
    nodes = {}
    for name, (_, values, transform, _, kind) in records.items():
        rows, cols = np.shape(values)[-2:]
        y = transform.f + transform.e * (np.arange(rows) + 0.5)
        x = transform.c + transform.a * (np.arange(cols) + 0.5)
        node = xr.DataArray(np.asarray(grid_nodes(values, kind), dtype=np.float64), dims=("y", "x"),
                            coords={"y": y, "x": x}, name=name, attrs={"units": "deg"})
        node = node.rio.write_transform(transform)
        nodes[name] = node.rio.write_crs(like.rio.crs) if like.rio.crs is not None else node
    return nodes


def normalize_at_nodes(reflectance: xr.DataArray, angles: Mapping[str, xr.DataArray], params: ParameterTable,
                       reference: ReferenceGeometry, *, limits: tuple[float, float] | None = DEFAULT_LIMITS,
                       extrapolate: bool = False, jump: float | None = None,
                       flip_view_azimuth: bool = False) -> Normalized:
    """Normalize ``reflectance`` with the factor evaluated at the angle grid's nodes (module
    docstring) and interpolated bilinearly to the pixels.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x)
        Reflectance, dask-backed, with a ``wavelength`` coordinate if the table needs one.
    angles : mapping of str to xarray.DataArray (y, x)
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] as a sensor reader gives them from a coarse grid
        (:func:`node_angles`).
    params : ParameterTable
        One class (id 1), applied to every pixel.
    reference : ReferenceGeometry
        Resolved: a fixed sun zenith [deg] or ``"observed"`` (each node's own), view zenith and
        relative azimuth [deg].
    limits, extrapolate :
        As for :func:`brdfcorr.correction.normalize`.
    jump : float or None, default None
        In grid cells whose four nodes' view azimuths span more than this [deg]
        (:func:`azimuth_span`; e.g. :data:`JUMP`), the factor of each pixel from its own
        interpolated angles; None: the factor interpolated everywhere (sen2nbar's method).
    flip_view_azimuth : bool, default False
        As for :func:`brdfcorr.correction.normalize`: the view azimuths are from the sensor.

    Returns
    -------
    Normalized
        The corrected cube (the input's dims, coords and chunks) and its QA layer, both lazy.
    """
    reference = with_mean_sza(reference, angles["sza"])  # the pixels' mean, not the nodes'
    nodes = node_angles(angles)
    template = nodes["sza"]
    band_dim = reflectance.dims[0]
    band_coords = {name: coord for name, coord in reflectance.coords.items() if coord.dims == (band_dim,)}
    ones = xr.DataArray(np.ones((reflectance.sizes[band_dim], *template.shape), dtype=np.float64),
                        dims=(band_dim, "y", "x"), coords={**band_coords, "y": template.y, "x": template.x})
    ones = ones.rio.write_transform(template.rio.transform())
    if template.rio.crs is not None:
        ones = ones.rio.write_crs(template.rio.crs)
    classes = xr.ones_like(template, dtype=np.uint8)
    factor, node_qa = normalize(ones, classes, nodes, params, reference, limits=limits, extrapolate=extrapolate,
                                flip_view_azimuth=flip_view_azimuth)
    _, _, source, target, _ = angles["sza"].encoding[GRID_SOURCE]
    node_values = np.concatenate([factor.values, ((node_qa.values & QA.LIMITED) > 0)[np.newaxis]]).astype(np.float64)
    jumps = azimuth_span(nodes["vaa"].values) > (np.inf if jump is None else jump)
    grids = {name: (angles[name].encoding[GRID_SOURCE][1], angles[name].encoding[GRID_SOURCE][4]) for name in ANGLES}
    per_pixel = partial(_pixel_factors, grids=grids, jumps=jumps,
                        source=source, target=target, like=ones.isel(y=slice(0, 1), x=slice(0, 1)),
                        evaluate=partial(normalize, params=params, reference=reference, limits=limits,
                                         extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth))
    pairs = da.map_blocks(_corrected_block, reflectance.data, dtype=reflectance.dtype, meta=np.empty((0, 0, 0)),
                          node_values=node_values, source=source, target=target, per_pixel=per_pixel)
    return normalized_from_pairs(pairs, reflectance, band_dim, {
        "brdf_reference": reference.describe(), "brdf_limits": describe_limits(limits),
        "brdf_factor_at": "the nodes of the angle grid, interpolated bilinearly to the pixels"})


def normalized_from_pairs(pairs: da.Array, reflectance: xr.DataArray, band_dim, attrs: Mapping) -> Normalized:
    """The corrected cube (``reflectance``'s dims, coords and attrs, with ``attrs`` added) and its
    QA layer from the (corrected, qa) pairs of a ``map_blocks`` over ``reflectance.data``."""
    corrected_data, qa_data = split_pairs(pairs, reflectance.dtype)
    corrected = xr.DataArray(corrected_data, dims=reflectance.dims, coords=reflectance.coords, name=reflectance.name,
                             attrs={**reflectance.attrs, **attrs})
    spatial = {name: coord for name, coord in reflectance.coords.items() if band_dim not in coord.dims}
    qa = xr.DataArray(qa_data, dims=reflectance.dims[1:], coords=spatial, name="qa",
                      attrs=qa_attrs("BRDF normalization quality flags"))
    return Normalized(corrected, qa)


def _cells(positions: np.ndarray, nodes: int) -> np.ndarray:
    """The grid cell (between nodes k and k + 1) of each position in node indices, the outermost
    cells beyond the outermost nodes."""
    return np.clip(np.floor(positions), 0, nodes - 2).astype(np.intp)


def _pixel_factors(rows: slice, cols: slice, *, grids: Mapping[str, tuple], jumps: np.ndarray, source, target,
                   like: xr.DataArray, evaluate: Callable) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pixels ``rows`` x ``cols`` in grid cells with an azimuth jump (``jumps``, per cell):
    their mask (y, x), the factor of every band (band, n) from their own interpolated angles
    (``grids``: each layer's coarse values and interpolation kind as :func:`to_grid` recorded
    them, so that the pixels get the angles of the layers), as :func:`normalize` evaluates it
    (``evaluate``: it with the table, reference and limits bound), and their limited flags (n,)."""
    rows_at, cols_at = coarse_positions(source, target, np.arange(rows.start, rows.stop),
                                        np.arange(cols.start, cols.stop))
    mask = jumps[_cells(rows_at, jumps.shape[0] + 1)[:, None], _cells(cols_at, jumps.shape[1] + 1)[None, :]]
    if not mask.any():
        return mask, np.empty((like.shape[0], 0)), np.empty(0, bool)
    angles = {name: xr.DataArray(interpolate_window(values, source, target, rows, cols, angle=kind)[mask][np.newaxis],
                                 dims=("y", "x"))
              for name, (values, kind) in grids.items()}
    ones = xr.DataArray(np.ones((like.shape[0], 1, int(mask.sum()))), dims=like.dims,
                        coords={name: coord for name, coord in like.coords.items() if coord.dims == like.dims[:1]})
    factor, qa = evaluate(ones, xr.ones_like(angles["sza"], dtype=np.uint8), angles)
    return mask, np.asarray(factor.values)[:, 0], (np.asarray(qa.values)[0] & QA.LIMITED) > 0


def _corrected_block(reflectance: np.ndarray, *, node_values: np.ndarray, source, target, per_pixel: Callable,
                     block_info=None):
    """One (band, y, x) block: the reflectance times the factor of its bands interpolated from the
    nodes (``node_values``: the factor per band, then the nodes' limited flags), or in the grid
    cells with an azimuth jump the factor from each pixel's own angles (``per_pixel``:
    :func:`_pixel_factors`), and its QA flags (1, y, x); both as one pair
    (:func:`brdfcorr.correction.blocks.split_pairs`)."""
    (band0, band1), (row0, row1), (col0, col1) = block_info[0]["array-location"]
    window = interpolate_window(node_values[[*range(band0, band1), -1]], source, target, slice(row0, row1),
                                slice(col0, col1))
    mask, factors, limited = per_pixel(slice(row0, row1), slice(col0, col1))
    window[:-1, mask] = factors[band0:band1]
    window[-1, mask] = limited
    with np.errstate(over="ignore"):  # a product beyond the precision: inf, nodata below
        corrected = (reflectance * window[:-1]).astype(reflectance.dtype)
    invalid = ~np.isfinite(corrected)
    if corrected.dtype.kind == "f":  # +-inf input (or a product beyond the precision) is nodata, as per pixel
        corrected[invalid] = np.nan
    qa = np.zeros((1, *reflectance.shape[1:]), dtype=np.uint8)
    # as per pixel: limited wherever the factor was, nodata OR-ed in (a band chunk's flags must
    # not depend on which other bands share its chunk)
    qa[0, window[-1] > 0] = QA.LIMITED
    set_flags(qa[0], invalid.any(axis=0), QA.NODATA)
    return corrected, qa
