"""The agreement of two overlapping flight lines, before and after a correction.

:func:`assess_overlap` takes the difference in the overlap (other line minus this one, on this
line's grid via rioxarray's ``reproject_match``): RMSE, mean absolute difference and bias per
band, before and after, with a histogram and a small map of the difference.
:func:`overlap_report` turns the result into a plain dict (NaN as ``None``, valid JSON).
"""

from __future__ import annotations

import math
import warnings

import dask
import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr
from rasterio.enums import Resampling

from brdfcorr.analysis._assess_common import STAGES, _band_coords, _band_list, _divide, _json_numbers
from brdfcorr.errors import InputError

__all__ = ["assess_overlap", "overlap_report"]


def _overlap_box(this: xr.DataArray, other: xr.DataArray) -> tuple[float, float, float, float]:
    """The bounds of the overlap in ``this``'s CRS; an :class:`InputError` when there is none."""
    for name, line in (("this line", this), ("the other line", other)):
        if line.rio.crs is None:
            raise InputError(f"{name} has no CRS: the overlap of two lines needs georeferenced rasters")
    left, bottom, right, top = this.rio.bounds()
    o_left, o_bottom, o_right, o_top = other.rio.transform_bounds(this.rio.crs)
    box = (max(left, o_left), max(bottom, o_bottom), min(right, o_right), min(top, o_top))
    resolution = np.abs(this.rio.resolution())
    if box[2] - box[0] < resolution[0] or box[3] - box[1] < resolution[1]:
        raise InputError("the two lines do not overlap (their bounds share less than one pixel)")
    return box


def _difference_statistics(difference: np.ndarray, level: np.ndarray) -> dict[str, np.ndarray]:
    """Per band (first axis) over the pixels (second axis): bias, MAD, RMSE, level, relative RMSE."""
    with np.errstate(invalid="ignore", divide="ignore"):
        bias = difference.mean(axis=1) if difference.shape[1] else np.full(len(difference), np.nan)
        mad = np.abs(difference).mean(axis=1) if difference.shape[1] else bias
        rmse = np.sqrt((difference**2).mean(axis=1)) if difference.shape[1] else bias
        mean = level.mean(axis=1) if level.shape[1] else bias
    return {"bias": bias, "mad": mad, "rmse": rmse, "mean": mean, "relative_rmse": 100.0 * _divide(rmse, mean)}


def _coarse_map(values: np.ndarray, size: int) -> np.ndarray:
    """Block means of a (y, x) map, at most ``size`` cells on the longer side (NaN ignored)."""
    factor = max(1, math.ceil(max(values.shape) / size))
    ny, nx = (values.shape[0] // factor) * factor, (values.shape[1] // factor) * factor
    if ny == 0 or nx == 0:
        return values
    blocks = values[:ny, :nx].reshape(ny // factor, factor, nx // factor, factor)
    with warnings.catch_warnings():  # cells without a compared pixel: NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(blocks, axis=(1, 3))


def _checked_options(before: xr.DataArray, after: xr.DataArray, other_before: xr.DataArray,
                     other_after: xr.DataArray, resampling: str, histogram_bins: int, map_size: int) -> Resampling:
    """The rasterio resampling method named ``resampling``, after checking the options and that the
    lines' before and after cubes agree in shape and the two lines in band count (else InputError)."""
    try:
        method = Resampling[resampling]
    except KeyError:
        raise InputError(f"resampling {resampling!r} is not a rasterio resampling method, e.g. nearest, "
                         "bilinear") from None
    if histogram_bins < 2 or map_size < 1:
        raise InputError("histogram_bins must be >= 2 and map_size >= 1")
    for name, pair in (("this", (before, after)), ("the other", (other_before, other_after))):
        if pair[0].shape != pair[1].shape:
            raise InputError(f"{name} line's before and after reflectance differ in shape: {pair[0].shape}, "
                             f"{pair[1].shape}")
    if before.shape[0] != other_before.shape[0]:
        raise InputError(f"the lines have different band counts: {before.shape[0]} and {other_before.shape[0]}")
    return method


def _overlap_cubes(before: xr.DataArray, after: xr.DataArray, other_before: xr.DataArray, other_after: xr.DataArray,
                   box: tuple, method: Resampling) -> list[np.ndarray]:
    """This line's before and after cut to the overlap ``box`` (read once), then the other line's
    cut to it and brought onto this line's grid (``reproject_match``): four (band, y, x) float64 arrays."""
    this = list(dask.compute(*[line.rio.clip_box(*box) for line in (before, after)]))  # the overlap, read once
    other = [line.rio.clip_box(*box, crs=before.rio.crs).rio.reproject_match(this[0], resampling=method)
             for line in (other_before, other_after)]
    return [np.asarray(line.values, dtype=np.float64) for line in (*this, *other)]


def _histogram_edges(band_means: list[np.ndarray], bins: int) -> np.ndarray:
    """``bins`` + 1 edges [1] symmetric about 0 over the 99.5th percentile of the band-mean
    differences' magnitude (both stages), so that before and after share the bins."""
    reach = max((np.nanpercentile(np.abs(m), 99.5) for m in band_means if np.isfinite(m).any()), default=1.0)
    reach = reach if reach > 0 else 1e-6  # identical lines: a narrow histogram around 0
    return np.linspace(-reach, reach, bins + 1)


def assess_overlap(
    before: xr.DataArray, after: xr.DataArray, other_before: xr.DataArray, other_after: xr.DataArray, *,
    resampling: str = "nearest", histogram_bins: int = 81, map_size: int = 300,
) -> xr.Dataset:
    """The reflectance difference of two overlapping lines, before and after a correction.

    The overlap of the two lines' bounds is cut from this line (lazily, ``rio.clip_box``); the
    other line is cut to it and brought onto this line's grid with rioxarray's
    ``reproject_match`` (read into memory: only the overlap). The difference is other − this
    over the pixels valid in every band of all four rasters.

    Parameters
    ----------
    before, after : xarray.DataArray (band, y, x)
        This line, before and after the correction, georeferenced (rioxarray CRS and transform).
    other_before, other_after : xarray.DataArray (band, y, x)
        The other line, before and after, on any grid and CRS, with the same bands.
    resampling : str, default "nearest"
        rasterio resampling of the other line onto this grid (``"nearest"``, ``"bilinear"``, ...).
    histogram_bins : int, default 81
        Bins of the histogram of the band-mean difference, symmetric about 0 over the 99.5th
        percentile of its magnitude (before and after share the bins).
    map_size : int, default 300
        Longest side of the difference maps [cells] (block means of the band-mean difference).

    Returns
    -------
    xarray.Dataset
        ``pixels``: pixels compared; per (stage, band): ``bias`` = mean(d), ``mad`` = mean(|d|),
        ``rmse`` = sqrt(mean(d²)) [1], ``mean`` = mean((this + other) / 2) [1] and
        ``relative_rmse`` = 100 · rmse / mean [%]; ``histogram`` (stage, difference_bin) with
        ``difference_bin_edges``; ``difference_map`` (stage, map_y, map_x) of the band-mean
        difference [1], NaN outside the compared pixels.
    """
    method = _checked_options(before, after, other_before, other_after, resampling, histogram_bins, map_size)
    box = _overlap_box(before, other_before)
    cubes = _overlap_cubes(before, after, other_before, other_after, box, method)
    valid = np.logical_and.reduce([np.isfinite(cube).all(axis=0) for cube in cubes])
    differences = [cubes[2] - cubes[0], cubes[3] - cubes[1]]
    statistics = [_difference_statistics(d[:, valid], (c[:, valid] + o[:, valid]) / 2)
                  for d, c, o in ((differences[0], cubes[0], cubes[2]), (differences[1], cubes[1], cubes[3]))]
    band_means = [np.where(valid, d.mean(axis=0), np.nan) for d in differences]
    edges = _histogram_edges(band_means, histogram_bins)
    histograms = [np.histogram(np.clip(m[valid], edges[0], edges[-1]), edges)[0] for m in band_means]
    maps = [_coarse_map(m, map_size) for m in band_means]
    stat = {name: (("stage", "band"), np.stack([s[name] for s in statistics]),
                   {"units": "%" if name == "relative_rmse" else "1"}) for name in statistics[0]}
    return xr.Dataset(
        {**stat,
         "pixels": ((), int(valid.sum()), {"units": "1"}),
         "histogram": (("stage", "difference_bin"), np.stack(histograms), {"units": "1"}),
         "difference_map": (("stage", "map_y", "map_x"), np.stack(maps),
                            {"long_name": "band-mean difference, other - this", "units": "1"})},
        coords={"stage": ("stage", list(STAGES)), **_band_coords(before),
                "difference_bin": ("difference_bin", (edges[:-1] + edges[1:]) / 2, {"units": "1"}),
                "difference_bin_edges": (("difference_bin", "edge"), np.stack([edges[:-1], edges[1:]], axis=-1))},
        attrs={"difference": "other line - this line, on this line's grid", "resampling": resampling,
               "crs": str(before.rio.crs), "overlap_bounds": list(box)},
    )


def overlap_report(dataset: xr.Dataset) -> dict[str, object]:
    """The result of :func:`assess_overlap` as a JSON-serialisable dict: pixels, and per stage
    per band lists of ``rmse``, ``mad``, ``bias``, ``mean`` [1] and ``relative_rmse`` [%]; the
    ``summary`` gives the median relative RMSE over the bands [%] before and after."""
    report: dict[str, object] = {
        "difference": dataset.attrs["difference"], "resampling": dataset.attrs["resampling"],
        "overlap_bounds": dataset.attrs["overlap_bounds"], "crs": dataset.attrs["crs"],
        "pixels": int(dataset["pixels"]), "bands": _band_list(dataset),
        "units": {"rmse": "1", "mad": "1", "bias": "1", "mean": "1", "relative_rmse": "%"},
    }
    for stage in STAGES:
        report[stage] = {name: _json_numbers(dataset[name].sel(stage=stage).values)
                         for name in ("rmse", "mad", "bias", "mean", "relative_rmse")}
    report["summary"] = {f"median_relative_rmse_percent_{stage}": _json_numbers(
        np.nanmedian(dataset["relative_rmse"].sel(stage=stage).values)) if int(dataset["pixels"]) else None
        for stage in STAGES}
    return report


def _overlaps(a: xr.DataArray, b: xr.DataArray) -> bool:
    try:
        _overlap_box(a, b)
    except InputError:
        return False
    return True
