"""Benchmark: a real MODIS 16-day composite corrected to one fixed geometry, fitted pooled or with
each patch's level free (issue 37; run by hand, about a minute).

The data (``benchmarks/data/modis_myd13a1_h30v10/``, its README for the source and licence): MYD13A1
collection 6, tile h30v10, 1-16 June 2020, 480 x 480 pixels of 2.3 km, northern Australian savanna,
with per-pixel sun zenith, view zenith, relative azimuth and the day each pixel was taken from. A
composite takes each pixel from one of sixteen days, so neighbouring pixels were seen from
different orbits and sides of nadir, while land cover changes slowly across the tile.

Corrections, each to nadir view at a fixed sun zenith of 45 deg (:data:`REFERENCE`; not the observed
sun, which varies across the tile with the day and so with the view: a fixed reference measures the
correction alone):

- ``pooled``: NDVI quartile strata (:func:`brdfcorr.strata.ndvi_strata`), ``fit_classes`` with
  ``ross_thick_li_sparse`` and one level per stratum (``levels="pooled"``), ``normalize``;
- ``patch``: the same with each 8 x 8-pixel patch's level free (``levels="patch"``,
  :mod:`brdfcorr.fit.within`): the kernel shape is fitted to the differences between neighbours
  seen on other days, so land-cover differences across the tile never enter it;
- ``c-factor``: the fixed global RTLSR coefficients of Roy et al. (2016), Table 1.

Measure (issue 37's): each pixel's reflectance over the median of its 9 x 9 neighbourhood (land
cover varies little within 21 km, the view does: the ratio holds the view's effect), its
least-squares slope against the signed view zenith (positive towards forward scattering) per group
(``vegetation``: NDVI >= :data:`VEGETATION_NDVI`; ``other``) and band (red, NIR), in %/10 deg, with
a 1-sigma cluster-robust over the composite days (pixels of one day share their orbit and
atmosphere; issue 40). Goals: worst |slope| <= 0.3 %/10 deg and at most half the c-factor's, held
out. Held out twice: fitted on one colour of a checkerboard of 32-pixel squares and assessed on the
other (both ways), and fitted on the pixels of odd days and assessed on those of even days (both
ways); the in-sample figure beside.

    python benchmarks/bench_composite.py
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import numpy as np
import rioxarray
import xarray as xr
from numpy.lib.stride_tricks import sliding_window_view

from brdfcorr import normalize
from brdfcorr.fit import ClassModels, Sampling, fit_classes
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable
from brdfcorr.strata import ndvi, ndvi_strata

DATA = Path(__file__).resolve().parent / "data" / "modis_myd13a1_h30v10"
REFERENCE = {"sza": 45.0, "vza": 0.0, "raa": 0.0}
#: NDVI strata of the fit (quartiles), the assessment's vegetation threshold, the local window.
PERCENTILES, VEGETATION_NDVI, WINDOW = (25.0, 50.0, 75.0), 0.4, 9
#: Side [pixels] of the checkerboard's squares of the spatial hold-out, and of the patches.
SQUARE, PATCH = 32, 8
BANDS = {"red": 645.0, "nir": 858.5}
GOAL_WORST, GOAL_RATIO = 0.3, 0.5


def load(data: Path = DATA):
    """The composite (band, y, x) with wavelengths, its angles (sza, saa = 0, vza, vaa = raa: the
    relative azimuth is all the product gives) and its day layer."""
    image = rioxarray.open_rasterio(data / "reflectance.tif", masked=True).load()
    wavelengths = [float(text.split()[0]) for text in image.attrs["long_name"]]
    image = image.assign_coords(wavelength=("band", wavelengths))
    raw = rioxarray.open_rasterio(data / "angles.tif", masked=True).load()
    sza, vza, raa = (raw.isel(band=index, drop=True) for index in range(3))
    angles = xr.Dataset({"sza": sza, "saa": xr.zeros_like(sza), "vza": vza, "vaa": raa % 360.0})
    day = rioxarray.open_rasterio(data / "day.tif").isel(band=0, drop=True).values
    return image, angles, day


def roy2016_table() -> ParameterTable:
    """Roy et al. (2016) Table 1 as class 1 (``correct --params roy2016``)."""
    return ParameterTable(classes=[ClassEntry(**load_coefficients("roy2016").table_entry(1))])


def fit_and_correct(image, angles, strata, fit_on: np.ndarray, levels: str) -> np.ndarray:
    """The strata fitted on the pixels ``fit_on`` with ``levels``, the whole composite corrected."""
    classes = strata.where(xr.DataArray(fit_on, dims=("y", "x")), 0).astype(np.int32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse"),
                             sampling=Sampling(levels=levels, patch_size=PATCH, max_samples=200_000))
    corrected, _ = normalize(image, strata, angles, result.table, REFERENCE)
    return np.asarray(corrected.values)


def local_ratio(cube: np.ndarray) -> np.ndarray:
    """Each pixel over the NaN-median of its ``WINDOW`` x ``WINDOW`` neighbourhood, per band."""
    half = WINDOW // 2
    padded = np.pad(cube, ((0, 0), (half, half), (half, half)), constant_values=np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows
        median = np.nanmedian(sliding_window_view(padded, (WINDOW, WINDOW), axis=(1, 2)), axis=(-2, -1))
    return cube / median


def clustered_slope(x: np.ndarray, y: np.ndarray, clusters: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of y on x and its CR1 1-sigma over ``clusters``."""
    design = np.column_stack([np.ones_like(x), x])
    bread = np.linalg.inv(design.T @ design)
    beta = bread @ design.T @ y
    residual = y - design @ beta
    _, codes = np.unique(clusters, return_inverse=True)
    scores = np.stack([np.bincount(codes.ravel(), weights=design[:, j] * residual) for j in range(2)], axis=1)
    groups = scores.shape[0]
    meat = scores.T @ scores * groups / max(groups - 1, 1)
    return float(beta[1]), float(np.sqrt((bread @ meat @ bread)[1, 1]))


def slopes(cube: np.ndarray, signed: np.ndarray, groups: dict[str, np.ndarray], day: np.ndarray,
           wavelengths: np.ndarray, assess_on: np.ndarray) -> dict[str, tuple[float, float]]:
    """``{"group band": (slope, sigma)}`` [%/10 deg] of the local ratio against the signed view zenith."""
    ratio = local_ratio(cube)
    out = {}
    for name, mask in groups.items():
        for band, centre in BANDS.items():
            values = ratio[int(np.argmin(np.abs(wavelengths - centre)))]
            keep = mask & assess_on & np.isfinite(values) & np.isfinite(signed)
            slope, sigma = clustered_slope(signed[keep], values[keep], day[keep])
            out[f"{name} {band}"] = (1000.0 * slope, 1000.0 * sigma)
    return out


def worst(values: dict[str, tuple[float, float]]) -> float:
    return max(abs(slope) for slope, _ in values.values())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    args = parser.parse_args()
    start = time.perf_counter()
    image, angles, day = load(args.data)
    wavelengths = image["wavelength"].values
    raw = np.asarray(image.values)
    index = np.asarray(ndvi(image).values)
    strata = ndvi_strata(image, percentiles=PERCENTILES).classes
    signed = angles["vza"].values * np.sign(-np.cos(np.radians(angles["vaa"].values)))
    groups = {"vegetation": index >= VEGETATION_NDVI, "other": index < VEGETATION_NDVI}
    rows, columns = np.indices(day.shape)
    black = (rows // SQUARE + columns // SQUARE) % 2 == 0
    odd = day % 2 == 1
    everywhere = np.ones(day.shape, bool)
    cfactor, _ = normalize(image, xr.ones_like(strata), angles, roy2016_table(), REFERENCE, extrapolate=True)
    cfactor = np.asarray(cfactor.values)
    splits = {"in sample": [(everywhere, everywhere)],
              "checkerboard": [(black, ~black), (~black, black)],
              "by day (odd/even)": [(odd, ~odd), (~odd, odd)]}
    print(f"MYD13A1 h30v10 composite, {image.sizes['y']} x {image.sizes['x']}, corrected to nadir at "
          f"sza {REFERENCE['sza']:g} deg; slope of pixel / {WINDOW}x{WINDOW} median against signed vza "
          f"[%/10 deg], 1-sigma clustered by composite day")
    for split, folds in splits.items():
        for number, (fit_on, assess_on) in enumerate(folds):
            results = {"raw": slopes(raw, signed, groups, day, wavelengths, assess_on),
                       "c-factor": slopes(cfactor, signed, groups, day, wavelengths, assess_on)}
            for levels in ("pooled", "patch"):
                corrected = fit_and_correct(image, angles, strata, fit_on, levels)
                results[levels] = slopes(corrected, signed, groups, day, wavelengths, assess_on)
            print(f"\n{split}, fold {number}:")
            print(f"  {'group band':16s}" + "".join(f"{method:>16s}" for method in results))
            for key in results["raw"]:
                print(f"  {key:16s}" + "".join(f"{results[m][key][0]:+8.2f}±{results[m][key][1]:<6.2f}"
                                              for m in results))
            limit = worst(results["c-factor"])
            for levels in ("pooled", "patch"):
                value = worst(results[levels])
                met = value <= GOAL_WORST and value <= GOAL_RATIO * limit
                print(f"  {levels}: worst {value:.2f} (goal <= {GOAL_WORST} and <= half the c-factor's "
                      f"{limit:.2f}: {'met' if met else 'MISSED'}); raw {worst(results['raw']):.2f}")
    print(f"\n{time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
