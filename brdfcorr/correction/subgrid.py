"""The per-pixel correction factor of a coarse angle grid, evaluated on a fine sample grid and
interpolated, with a checked error.

Angles given on a coarse grid (the 5 km Sentinel-2 grids of ``MTD_TL.xml``) are interpolated
bilinearly to the pixels (:func:`brdfcorr.io.sensors.grids.to_grid`), so within one cell of that
grid every angle is a smooth function of the pixel's position and so is the factor
f(ref) / f(obs) (:func:`brdfcorr.correction.normalize`). Evaluating the angles and the two
kernels at every pixel is then mostly redundant work. Here, per block:

1. Along each axis, the *coarse* samples: the first and last pixel, the two pixels either side
   of every node of the angle grid (where the interpolated angles have a kink) and, between
   those, steps of at most 1 / :data:`SUBDIVISIONS` of a grid cell (:func:`axis_samples`); the
   *fine* samples: those and the pixel midway between each two (steps of at most 1/32 of a
   cell, about 156 m on a 5 km grid).
2. The factor is evaluated exactly (:func:`normalize`, unclipped) at the fine samples.
3. Each cell of the coarse samples is checked: its factor interpolated bilinearly from its four
   corners against the exact factor at the fine samples in and around it. For a smooth factor
   the error of the interpolation from the fine samples is about a quarter of this (second order
   in the spacing). Cells where it exceeds :data:`TOLERANCE` (relative, any band) or where a
   sample has no valid factor get the factor of each pixel from its own interpolated angles,
   as :func:`normalize` evaluates it: along the nadir line, where the interpolated view
   azimuth turns by up to 180 deg within a few pixels, and at invalid geometries.
4. Elsewhere the factor is interpolated bilinearly from the fine samples (two 1-D linear
   interpolations), then clipped to the limits, per pixel.

On the whole real T23LLF tile (``tests/correction/test_subgrid.py``, each pixel of a 60 m
grid: the samples lie as many metres apart as at 10 m and 20 m) the result is within 0.00004 %
of the per-pixel factor of :func:`normalize` with the view grids averaged over the bands and
0.00002 % with B02's own, float32 rounding, since the view direction is interpolated as a vector
(0.0015 % and 0.0017 % before; the goal of issue 41: 0.01 %), and less time goes into evaluating
pixels one by one at finer pixels (the samples are fewer per pixel).
It suits one smooth correction over the whole image: one class, no class map, no terrain, no
uncertainty layer, no coefficients continuous in NDVI and no bad bands
(:func:`suits_subgrid`); otherwise the factor is evaluated at every pixel.

QA flags: those :func:`normalize` gives at pixels evaluated one by one; elsewhere ``nodata``
where the reflectance or the factor is not finite and ``limited`` where the factor was clipped.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from functools import partial

import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.correction.nodes import normalized_from_pairs
from brdfcorr.correction.normalization import Normalized, normalize
from brdfcorr.correction.qa import QA
from brdfcorr.correction.reference import describe_limits, with_mean_sza
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.io.sensors.grids import GRID_SOURCE, coarse_positions, grid_nodes, interpolate_at
from brdfcorr.params import ParameterTable, ReferenceGeometry

__all__ = ["normalize_on_subgrid", "suits_subgrid", "axis_samples", "SUBDIVISIONS", "TOLERANCE"]

ANGLES = ("sza", "saa", "vza", "vaa")
#: Cells of the coarse samples per cell of the angle grid along each axis (the fine samples
#: halve them): 16 gives about 156 m between fine samples on a 5 km grid. With 8, a fifth of the
#: cells of a real tile's 20 m blocks failed the check (4.5 % of the pixels evaluated one by one,
#: half of the factor's time, on the SAFE of ``benchmarks/bench_busy.py --job nbar``); with 16
#: none did, for 4 times as many samples (still under 1 % of the pixels).
SUBDIVISIONS = 16
#: Largest relative error [-] of a coarse-sample cell's interpolation (step 3 of the module
#: docstring) below which its pixels take the factor interpolated from the fine samples.
TOLERANCE = 2.5e-5


def suits_subgrid(reflectance: xr.DataArray, angles: Mapping[str, xr.DataArray], params: ParameterTable) -> bool:
    """Whether :func:`normalize_on_subgrid` gives the per-pixel factor of ``reflectance`` (float,
    (band, y, x)): every angle layer interpolated from one coarse grid onto the image's grid
    (:data:`~brdfcorr.io.sensors.grids.GRID_SOURCE`), a table of one class without bad bands
    and without coefficients continuous in NDVI. A class map, terrain or an uncertainty layer
    the caller rules out."""
    found = [angles[name].encoding.get(GRID_SOURCE) if name in angles else None for name in ANGLES]
    records = [record for record in found if record is not None]
    if len(records) != len(ANGLES) or reflectance.ndim != 3 or reflectance.dtype.kind != "f":
        return False
    grids = {(tuple(record[0]), record[2], record[3], np.shape(record[1])[-2:]) for record in records}
    shape = (reflectance.shape[1], reflectance.shape[2])
    if len(grids) != 1 or next(iter(grids))[0] != shape:
        return False
    classes = params.classes
    return len(classes) == 1 and params.ndvi_interpolation is None and not classes[0].bad_bands


def axis_samples(positions: np.ndarray, nodes: int, subdivisions: int = SUBDIVISIONS) -> np.ndarray:
    """Sample pixel indices along one axis (module docstring, step 1), sorted and distinct.

    Parameters
    ----------
    positions : numpy.ndarray (n,)
        The pixels' positions in coarse cell indices (centre of node k at k), monotonic.
    nodes : int
        Number of nodes of the coarse grid along this axis.
    subdivisions : int
        Steps per coarse cell (at most ``1 / subdivisions`` of a cell each).

    Returns
    -------
    numpy.ndarray of int
        The first and last pixel, the last pixel before and the first after every node, and
        evenly spaced pixels between those.
    """
    size = positions.size
    piece = np.clip(np.floor(positions), -1, nodes - 1)  # -1 before the first node, nodes - 1 after the last
    change = np.flatnonzero(np.diff(piece)) + 1
    starts, ends = np.concatenate([[0], change]), np.concatenate([change - 1, [size - 1]])
    per_pixel = abs(positions[-1] - positions[0]) / max(size - 1, 1)  # coarse cells per pixel
    step = max(1.0, 1.0 / (per_pixel * subdivisions)) if per_pixel > 0 else float(size)
    samples = [np.rint(np.linspace(start, end, int(np.ceil((end - start) / step)) + 1))
               for start, end in zip(starts, ends)]
    return np.unique(np.concatenate(samples).astype(np.intp))


def _linear_weights(samples: np.ndarray, at: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear interpolation between ``samples`` (sorted distinct pixel indices) at pixel indices
    ``at`` within them: the lower and upper sample's index in ``samples`` and the upper's weight."""
    if samples.size == 1:
        zero = np.zeros(at.size, np.intp)
        return zero, zero, np.zeros(at.size)
    lower = np.clip(np.searchsorted(samples, at, side="right") - 1, 0, samples.size - 2)
    return lower, lower + 1, (at - samples[lower]) / (samples[lower + 1] - samples[lower])


def interpolate_samples(values: np.ndarray, rows: tuple, cols: tuple) -> np.ndarray:
    """``values`` (..., r, c) at samples interpolated bilinearly (:func:`_linear_weights` along
    each axis: ``rows`` and ``cols``), first along the columns, then the rows, each as
    ``lower + t (upper - lower)``: the rows' differences are taken between the few samples, so
    the full-size result costs one gather, one product and one sum in place."""
    lower, upper, t = cols
    along = values[..., lower] + (values[..., upper] - values[..., lower]) * t.astype(values.dtype)
    lower, _, t = rows  # the upper sample is lower + 1 (_linear_weights)
    result = along[..., lower, :]
    if along.shape[-2] > 1:  # else every row is the one sample's (t = 0)
        step = np.diff(along, axis=-2)[..., lower, :]
        step *= t.astype(values.dtype)[:, None]
        result += step
    return result


def angles_at(grids: Mapping[str, tuple], rows_at: np.ndarray, cols_at: np.ndarray) -> dict[str, np.ndarray]:
    """The angles [deg] at the coarse positions ``rows_at`` x ``cols_at`` of the coarse grids
    ``grids`` (each layer's values and interpolation kind as
    :func:`brdfcorr.io.sensors.grids.to_grid` recorded them), as it interpolates the image's
    pixels (:func:`~brdfcorr.io.sensors.grids.interpolate_at`)."""
    return {name: interpolate_at(values, rows_at, cols_at, angle=kind) for name, (values, kind) in grids.items()}


def normalize_on_subgrid(reflectance: xr.DataArray, angles: Mapping[str, xr.DataArray], params: ParameterTable,
                         reference: ReferenceGeometry, *, limits: tuple[float, float] | None = DEFAULT_LIMITS,
                         extrapolate: bool = False, flip_view_azimuth: bool = False,
                         subdivisions: int = SUBDIVISIONS, tolerance: float = TOLERANCE) -> Normalized:
    """Normalize ``reflectance`` with the per-pixel factor of :func:`normalize`, evaluated on a
    fine sample grid and interpolated where that is within ``tolerance`` (module docstring).

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x)
        Reflectance (floats), dask-backed, with a ``wavelength`` coordinate if the table needs one.
    angles : mapping of str to xarray.DataArray (y, x)
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] interpolated from one coarse grid
        (:func:`suits_subgrid`).
    params : ParameterTable
        One class, applied to every pixel.
    reference : ReferenceGeometry
        Resolved: a fixed sun zenith [deg] or ``"observed"``, view zenith and relative azimuth [deg].
    limits, extrapolate, flip_view_azimuth :
        As for :func:`brdfcorr.correction.normalize`.
    subdivisions : int, default :data:`SUBDIVISIONS`
        Cells of the coarse samples per cell of the angle grid (:func:`axis_samples`).
    tolerance : float, default :data:`TOLERANCE`
        Relative error [-] of a coarse-sample cell above which its pixels are evaluated one by one.

    Returns
    -------
    Normalized
        The corrected cube (the input's dims, coords and chunks) and its QA layer, both lazy.
    """
    reference = with_mean_sza(reference, angles["sza"])  # the pixels' mean, not each block's samples'
    records = {name: angles[name].encoding[GRID_SOURCE] for name in ANGLES}
    _, _, source, target, _ = records["sza"]
    grids = {name: (np.asarray(record[1], dtype=np.float64), record[4]) for name, record in records.items()}
    nodes = {name: grid_nodes(values, kind) for name, (values, kind) in grids.items()}
    band_dim = reflectance.dims[0]
    band_coords = {name: coord for name, coord in reflectance.coords.items() if coord.dims == (band_dim,)}
    evaluate = partial(_exact, class_id=params.classes[0].id, band_dim=band_dim, band_coords=band_coords,
                       n_bands=reflectance.sizes[band_dim],
                       evaluate=partial(normalize, params=params, reference=reference, limits=None,
                                        extrapolate=extrapolate, flip_view_azimuth=flip_view_azimuth))
    # normalize's checks of the table against the bands and of the reference, here at the nodes
    # (a few hundred values), as normalize makes them before any block is computed
    evaluate(nodes, slice(0, reflectance.sizes[band_dim]))
    pairs = da.map_blocks(_subgrid_block, reflectance.data, dtype=reflectance.dtype, meta=np.empty((0, 0, 0)),
                          grids=grids, source=source, target=target, evaluate=evaluate, limits=limits,
                          subdivisions=subdivisions, tolerance=tolerance)
    return normalized_from_pairs(pairs, reflectance, band_dim, {"brdf_reference": reference.describe(),
                                                                "brdf_limits": describe_limits(limits)})


def _exact(angles: Mapping[str, np.ndarray], bands: slice, *, class_id: int, band_dim: Hashable, band_coords: Mapping,
           n_bands: int, evaluate) -> tuple[np.ndarray, np.ndarray]:
    """The unclipped factor (band, ...) of the bands ``bands`` and the QA flags (...) at
    ``angles`` (arrays of one shape, 1-D or 2-D [deg]), as :func:`normalize` (``evaluate``, the
    table and reference bound) gives them at pixels of these angles. Every one of the image's
    ``n_bands`` bands is evaluated (a table given per band by position fits the whole image, not
    a chunk of its bands), those of ``bands`` are returned."""
    shape = next(iter(angles.values())).shape
    flat = (1, int(np.prod(shape)))
    layers = {name: xr.DataArray(np.reshape(values, flat), dims=("y", "x")) for name, values in angles.items()}
    ones = xr.DataArray(np.ones((n_bands, *flat)), dims=(band_dim, "y", "x"), coords=dict(band_coords))
    classes = xr.DataArray(np.full(flat, class_id, dtype=np.int32), dims=("y", "x"))
    factor, qa = evaluate(ones, classes, layers)
    picked = np.asarray(factor.values)[bands]
    return picked.reshape(picked.shape[0], *shape), np.asarray(qa.values).reshape(shape)


def _structured(coarse: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fine samples of an axis from its coarse ones: the coarse samples with the pixel midway
    between each two (``2 m - 1`` entries, a midpoint equal to a coarse sample where two are
    neighbours), and those distinct."""
    full = np.empty(2 * coarse.size - 1, dtype=np.intp)
    full[::2], full[1::2] = coarse, (coarse[:-1] + coarse[1:]) // 2
    return full, np.unique(full)


def _checked_cells(fine: np.ndarray, rows: tuple, cols: tuple) -> np.ndarray:
    """Per cell of the coarse samples (m - 1, k - 1), the largest relative difference [-] over
    the bands and the fine samples in the closed cell between the exact factor ``fine`` (band,
    2 m - 1, 2 k - 1) and its interpolation from the cell's corners (``rows``, ``cols``: the
    weights of the fine samples between the coarse ones); inf where a sample has no factor."""
    coarse = fine[:, ::2, ::2]
    with np.errstate(divide="ignore", invalid="ignore"):
        error = np.max(np.abs(interpolate_samples(coarse, rows, cols) - fine) / np.abs(fine), axis=0)
    error[~np.isfinite(error)] = np.inf
    m, k = coarse.shape[1] - 1, coarse.shape[2] - 1
    return np.max([error[i:i + 2 * m:2, j:j + 2 * k:2] for i in range(3) for j in range(3)], axis=0)


def _cell_of(samples: np.ndarray, size: int) -> np.ndarray:
    """Per pixel 0 .. size - 1, the cell between two neighbouring ``samples`` that holds it."""
    return np.clip(np.searchsorted(samples, np.arange(size), side="right") - 1, 0, samples.size - 2)


def _factor_window(positions: tuple[np.ndarray, np.ndarray], grids: Mapping[str, tuple], bands: slice,
                   evaluate, subdivisions: int, tolerance: float, dtype) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The unclipped factor (band, y, x) of one block whose pixels lie at the coarse
    ``positions`` (rows, cols) of the coarse grids ``grids`` (:func:`angles_at`), in ``dtype``,
    the QA flags of its pixels evaluated one by one (y, x) (module docstring, steps 1-4), and the
    least and largest factor evaluated: every interpolated one lies between them (the bilinear
    weights are positive)."""
    rows_at, cols_at = positions
    size = (rows_at.size, cols_at.size)
    shape = np.shape(next(iter(grids.values()))[0])[-2:]
    coarse = [axis_samples(at, n, subdivisions) for at, n in zip(positions, shape)]
    if min(sample.size for sample in coarse) < 2:  # a block one pixel wide: every pixel
        return _exact_everywhere(positions, grids, bands, evaluate, dtype)
    (full_r, fine_r), (full_c, fine_c) = (_structured(sample) for sample in coarse)
    fine, fine_qa = evaluate(angles_at(grids, rows_at[fine_r], cols_at[fine_c]), bands)
    structured = fine[:, np.searchsorted(fine_r, full_r)][:, :, np.searchsorted(fine_c, full_c)]
    cells = _checked_cells(structured, _linear_weights(coarse[0], full_r), _linear_weights(coarse[1], full_c))
    window = interpolate_samples(fine.astype(dtype), _linear_weights(fine_r, np.arange(size[0])),
                                 _linear_weights(fine_c, np.arange(size[1])))
    qa = np.zeros(size, dtype=np.uint8)
    qa[np.ix_(fine_r, fine_c)] = fine_qa
    flagged = cells > tolerance
    span = _span(fine)
    if flagged.any():
        span = _span(np.array([*span, *_evaluate_cells(window, qa, flagged, coarse, positions, grids, bands,
                                                          evaluate)]))
    return window, qa, span


def _span(factor: np.ndarray) -> tuple[float, float]:
    """The least and largest finite value of ``factor`` ((inf, -inf) where none is finite)."""
    finite = factor[np.isfinite(factor)]
    return (float(finite.min()), float(finite.max())) if finite.size else (np.inf, -np.inf)


def _exact_everywhere(positions, grids, bands, evaluate, dtype) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The factor and QA flags of every pixel of a block from its own angles, and the factor's span."""
    factor, qa = evaluate(angles_at(grids, *positions), bands)
    return factor.astype(dtype), qa.astype(np.uint8), _span(factor)


def _evaluate_cells(window: np.ndarray, qa: np.ndarray, flagged: np.ndarray, coarse: list[np.ndarray],
                    positions: tuple[np.ndarray, np.ndarray], grids, bands: slice, evaluate) -> tuple[float, float]:
    """Replace, in ``window`` (band, y, x) and ``qa`` (y, x), the factor and flags of the pixels
    in the ``flagged`` cells of the coarse samples by those from each pixel's own angles, in one
    evaluation: the angles of each row of cells on its flagged columns, then the pixels. Returns
    the span of their factors (:func:`_span`)."""
    cell_cols = _cell_of(coarse[1], window.shape[2])
    picked_rows: list[np.ndarray] = []
    picked_cols: list[np.ndarray] = []
    picked: dict[str, list[np.ndarray]] = {name: [] for name in grids}
    for row_cell in np.flatnonzero(flagged.any(axis=1)):
        rows = np.arange(coarse[0][row_cell], coarse[0][row_cell + 1] + 1)
        cols = np.flatnonzero(flagged[row_cell][cell_cols])
        for name, values in angles_at(grids, positions[0][rows], positions[1][cols]).items():
            picked[name].append(values.reshape(-1))
        picked_rows.append(np.repeat(rows, cols.size))
        picked_cols.append(np.tile(cols, rows.size))
    factor, flags = evaluate({name: np.concatenate(values) for name, values in picked.items()}, bands)
    at = (np.concatenate(picked_rows), np.concatenate(picked_cols))
    window[:, at[0], at[1]] = factor
    qa[at] = flags
    return _span(factor)


def _subgrid_block(reflectance: np.ndarray, *, grids: Mapping[str, tuple], source, target, evaluate,
                   limits: tuple[float, float] | None, subdivisions: int, tolerance: float, block_info=None):
    """One (band, y, x) block corrected with the factor of :func:`_factor_window`, clipped to
    ``limits``, and its QA flags (1, y, x); both as one pair
    (:func:`brdfcorr.correction.blocks.split_pairs`)."""
    (band0, band1), (row0, row1), (col0, col1) = block_info[0]["array-location"]
    positions = coarse_positions(source, target, np.arange(row0, row1), np.arange(col0, col1))
    window, qa, span = _factor_window(positions, grids, slice(band0, band1), evaluate, subdivisions, tolerance,
                                      reflectance.dtype)
    # 1e-6: the float32 rounding of interpolated factors near a limit
    if limits is not None and (span[0] < limits[0] * (1 + 1e-6) or span[1] > limits[1] * (1 - 1e-6)):
        # fmin/fmax pass NaN over: a band without a factor is nodata, not limited
        limited = (np.fmin.reduce(window, axis=0) < limits[0]) | (np.fmax.reduce(window, axis=0) > limits[1])
        np.clip(window, *limits, out=window)
        qa[limited] |= np.uint8(QA.LIMITED)
    with np.errstate(over="ignore", invalid="ignore"):  # a band sum is finite where every band is (one pass)
        corrected = np.multiply(reflectance, window, out=window, casting="unsafe")  # inf beyond the precision
        suspect = np.flatnonzero(~np.isfinite(np.add.reduce(corrected, axis=0)))
    if suspect.size:
        _flag_nodata(corrected, reflectance, qa, suspect)
    return corrected, qa[np.newaxis]


def _flag_nodata(corrected: np.ndarray, reflectance: np.ndarray, qa: np.ndarray, suspect: np.ndarray) -> None:
    """At the ``suspect`` pixels (flat indices; some value not finite, or a band sum overflowing):
    values not finite set to NaN (+-inf is nodata like NaN), and the pixel flagged ``nodata``
    where its reflectance is not finite in some band, or its factor, but for an invalid geometry
    (flagged so already), as :func:`normalize` flags them."""
    flat, flags = corrected.reshape(corrected.shape[0], -1), qa.reshape(-1)
    values = flat[:, suspect]
    finite = np.isfinite(values)
    no_reflectance = ~np.isfinite(reflectance.reshape(reflectance.shape[0], -1)[:, suspect]).all(axis=0)
    nodata = no_reflectance | (~finite.all(axis=0) & (flags[suspect] & QA.INVALID_GEOMETRY == 0))
    flat[:, suspect] = np.where(finite, values, np.nan)
    flags[suspect[nodata]] |= np.uint8(QA.NODATA)
