"""Benchmark: a real MODIS 16-day composite corrected to one fixed geometry, fitted pooled or with
each patch's level free (issue 37; run by hand, about three minutes).

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
- ``local``: a smoothly varying level (issue 37's part 2): each pixel's level is the mean
  reflectance of its ``WINDOW`` x ``WINDOW`` neighbourhood (the fitted pixels, the pixel itself left
  out), ``F_n``, over the mean of the model there, ``G_n``. The strata are fitted pooled to
  ``u_n = f_n G_n / F_n`` (at the truth ``f = s g`` with a level ``s`` smooth over the window,
  ``u = g``, whether or not the view varies within the window), ``G_n`` from the previous fit,
  starting from the pooled one (:data:`LOCAL_ROUNDS` rounds; ``u`` rescaled per band to the median
  of ``f``, since a correction is a ratio of the model and the scale cancels), the table applied to
  the composite itself. As :mod:`brdfcorr.fit.within`'s relative views, with overlapping windows
  instead of patches;
- ``c-factor``: the fixed global RTLSR coefficients of Roy et al. (2016), Table 1.

``--strata neighbourhood`` cuts the strata (of every fitted method) from the NDVI of each pixel's
``WINDOW`` x ``WINDOW`` neighbourhood's median reflectance instead of its own: a cover estimate
that does not depend on the pixel's own view (issue 37's part 2).

Measure (issue 37's): each pixel's reflectance over the median of its 9 x 9 neighbourhood (land
cover varies little within 21 km, the view does: the ratio holds the view's effect), its
least-squares slope against the signed view zenith (positive towards forward scattering) per group
(``vegetation``: NDVI >= :data:`VEGETATION_NDVI`; ``other``) and band (red, NIR), in %/10 deg, with
a 1-sigma cluster-robust over the composite days (pixels of one day share their orbit and
atmosphere; issue 40). Goals: worst |slope| <= 0.3 %/10 deg and at most half the c-factor's, held
out. Held out twice: fitted on one colour of a checkerboard of 32-pixel squares and assessed on the
other (both ways), and fitted on the pixels of odd days and assessed on those of even days (both
ways); the in-sample figure beside. Each hold-out is also *cross-fitted*: every pixel corrected by
the fit of the fold that left it out and all of them assessed together, twice the pixels of one
fold, so a 1-sigma about 1/sqrt(2) of a fold's. Beside each worst |slope|, what a perfect
correction would show with the same 1-sigmas (the median and 90th percentile of the worst of
slopes drawn as N(0, sigma)) and the chance of slopes at least as far from 0 if none were left
(chi^2 of slope / sigma, one degree of freedom each). A composite without a day layer (``--data
benchmarks/data/modis_mod09a1_h18v04``) is held out on the checkerboard only (``--square`` smaller
for a small cut), its 1-sigma clustered by ``PATCH`` x ``PATCH`` blocks instead of days.

    python benchmarks/bench_composite.py [--methods pooled,patch,local]
    python benchmarks/bench_composite.py --strata neighbourhood
    python benchmarks/bench_composite.py --methods pooled,patch,local --square 16 \\
        --data benchmarks/data/modis_mod09a1_h18v04
"""

from __future__ import annotations

import argparse
import time
import warnings
from functools import partial
from pathlib import Path

import numpy as np
import rioxarray
import xarray as xr
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import uniform_filter
from scipy.stats import chi2

from brdfcorr import normalize
from brdfcorr.fit import ClassModels, Sampling, fit_classes
from brdfcorr.fit.prior import ShapePrior
from brdfcorr.models import get_model
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
#: Rounds of the ``local`` fit (each a pooled fit at the previous fit's neighbourhood model mean).
LOCAL_ROUNDS = 4
RTLSR = get_model("ross_thick_li_sparse")


def load(data: Path = DATA):
    """The composite (band, y, x) with wavelengths, its angles (sza, saa = 0, vza, vaa = raa: the
    relative azimuth is all the product gives) and its day layer."""
    image = rioxarray.open_rasterio(data / "reflectance.tif", masked=True).load()
    wavelengths = [float(text.split()[0]) for text in image.attrs["long_name"]]
    image = image.assign_coords(wavelength=("band", wavelengths))
    raw = rioxarray.open_rasterio(data / "angles.tif", masked=True).load()
    sza, vza, raa = (raw.isel(band=index, drop=True) for index in range(3))
    angles = xr.Dataset({"sza": sza, "saa": xr.zeros_like(sza), "vza": vza, "vaa": raa % 360.0})
    if not (data / "day.tif").exists():
        return image, angles, None
    day = rioxarray.open_rasterio(data / "day.tif").isel(band=0, drop=True).values
    return image, angles, day


def roy2016_table() -> ParameterTable:
    """Roy et al. (2016) Table 1 as class 1 (``correct --params roy2016``)."""
    return ParameterTable(classes=[ClassEntry(**load_coefficients("roy2016").table_entry(1))])


def fitted_table(image, classes, angles, levels: str, prior: ShapePrior | None = None) -> ParameterTable:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse", prior=prior),
                           sampling=Sampling(levels=levels, patch_size=PATCH, max_samples=200_000)).table


def neighbourhood_mean(cube: np.ndarray) -> np.ndarray:
    """Mean (band, y, x) of the finite values of each pixel's ``WINDOW`` x ``WINDOW`` neighbourhood,
    the pixel itself left out (NaN where none)."""
    valid = np.isfinite(cube).astype(float)
    values = np.where(valid > 0, cube, 0.0)
    size = (1, WINDOW, WINDOW)
    total = uniform_filter(values, size, mode="constant") * WINDOW**2 - values
    count = uniform_filter(valid, size, mode="constant") * WINDOW**2 - valid
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0.5, total / count, np.nan)


def model_values(table: ParameterTable, strata: np.ndarray, angles, wavelengths) -> np.ndarray:
    """The fitted model (band, y, x) [sr^-1] of each pixel's stratum at its own geometry."""
    out = np.full((len(wavelengths), *strata.shape), np.nan)
    geometry = [angles[name].values.astype(float) for name in ("sza", "vza")]
    phi = (angles["vaa"].values - angles["saa"].values).astype(float)
    for class_id, entry in table.for_bands(wavelengths=list(wavelengths), extrapolate=True).items():
        where = strata == class_id
        params = {name: np.asarray(value, float)[:, None] for name, value in entry.params.items()}
        out[:, where] = RTLSR(geometry[0][where][None], geometry[1][where][None], phi[where][None], **params)
    return out


def local_table(image, classes, angles, fit_on: np.ndarray) -> ParameterTable:
    """The ``local`` fit (module docstring): pooled fits to ``u = f G / F``, :data:`LOCAL_ROUNDS` rounds."""
    observed = np.where(fit_on, np.asarray(image.values, dtype=float), np.nan)
    level, strata = neighbourhood_mean(observed), np.asarray(classes.values)
    table = fitted_table(image, classes, angles, "pooled")
    for _ in range(LOCAL_ROUNDS):
        model = np.where(fit_on, model_values(table, strata, angles, image["wavelength"].values), np.nan)
        relative = observed * neighbourhood_mean(model) / level
        relative *= (np.nanmedian(observed, axis=(1, 2)) / np.nanmedian(relative, axis=(1, 2)))[:, None, None]
        table = fitted_table(image.copy(data=relative.astype(np.float32)), classes, angles, "pooled")
    return table


def fit_and_correct(image, angles, strata, fit_on: np.ndarray, levels: str,
                    prior: ShapePrior | None = None) -> np.ndarray:
    """The strata fitted on the pixels ``fit_on`` with ``levels`` (or ``"local"``, the module
    docstring), the whole composite corrected."""
    classes = strata.where(xr.DataArray(fit_on, dims=("y", "x")), 0).astype(np.int32)
    if levels == "local":
        table = local_table(image, classes, angles, fit_on)
    else:
        table = fitted_table(image, classes, angles, levels, prior)
    corrected, _ = normalize(image, strata, angles, table, REFERENCE)
    return np.asarray(corrected.values)


def neighbourhood_median(cube: np.ndarray) -> np.ndarray:
    """The NaN-median of each pixel's ``WINDOW`` x ``WINDOW`` neighbourhood, per band."""
    half = WINDOW // 2
    padded = np.pad(cube, ((0, 0), (half, half), (half, half)), constant_values=np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN windows
        return np.nanmedian(sliding_window_view(padded, (WINDOW, WINDOW), axis=(1, 2)), axis=(-2, -1))


def local_ratio(cube: np.ndarray) -> np.ndarray:
    """Each pixel over the NaN-median of its ``WINDOW`` x ``WINDOW`` neighbourhood, per band."""
    return cube / neighbourhood_median(cube)


def strata_of(image, kind: str):
    """NDVI quartile strata of each pixel's own NDVI (``ndvi``) or of its neighbourhood's median
    reflectance (``neighbourhood``: a cover estimate that the pixel's own view barely moves, since
    its neighbours were seen from other orbits), 0 where the pixel itself is not finite."""
    if kind == "ndvi":
        return ndvi_strata(image, percentiles=PERCENTILES).classes
    values = np.asarray(image.values, dtype=float)
    median = image.copy(data=neighbourhood_median(values).astype(np.float32))
    strata = ndvi_strata(median, percentiles=PERCENTILES).classes
    return strata.where(xr.DataArray(np.all(np.isfinite(values), axis=0), dims=("y", "x")), 0).astype(strata.dtype)


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


def noise_floor(values: dict[str, tuple[float, float]], draws: int = 100_000) -> tuple[float, float]:
    """What a perfect correction would show: the median and 90th percentile of the worst |slope| of
    slopes drawn as N(0, sigma) with the measured 1-sigmas (independent draws, seeded)."""
    sigmas = np.array([sigma for _, sigma in values.values()])
    drawn = np.abs(np.random.default_rng(0).standard_normal((draws, sigmas.size)) * sigmas).max(axis=1)
    return float(np.median(drawn)), float(np.quantile(drawn, 0.9))


def chance(values: dict[str, tuple[float, float]]) -> float:
    """The probability of slopes at least this far from 0 under a perfect correction (chi^2 of the
    slopes over their 1-sigmas, one degree of freedom each)."""
    return float(chi2.sf(sum((slope / sigma) ** 2 for slope, sigma in values.values()), len(values)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--square", type=int, default=SQUARE, help="side [px] of the checkerboard's squares")
    parser.add_argument("--methods", default="pooled,patch", help="fitted methods, comma-separated "
                        "(pooled, patch, local)")
    parser.add_argument("--strata", choices=("ndvi", "neighbourhood"), default="ndvi",
                        help="strata of each pixel's NDVI or of its neighbourhood's median reflectance")
    parser.add_argument("--prior-spread", type=float, default=None,
                        help="fit with the kernel shape of Roy et al. (2016) as a prior of this spread "
                             "(fit-classes --prior roy2016 --prior-spread S)")
    args = parser.parse_args()
    start = time.perf_counter()
    image, angles, day = load(args.data)
    methods = args.methods.split(",")
    rows, columns = np.indices(image.shape[1:])
    by_day = day is not None
    if not by_day:  # 1-sigma clustered by blocks; no hold-out by day
        day = (rows // PATCH) * (columns.max() // PATCH + 1) + columns // PATCH
    wavelengths = image["wavelength"].values
    raw = np.asarray(image.values)
    index = np.asarray(ndvi(image).values)
    strata = strata_of(image, args.strata)
    signed = angles["vza"].values * np.sign(-np.cos(np.radians(angles["vaa"].values)))
    groups = {"vegetation": index >= VEGETATION_NDVI, "other": index < VEGETATION_NDVI}
    black = (rows // args.square + columns // args.square) % 2 == 0
    odd = day % 2 == 1
    everywhere = np.ones(day.shape, bool)
    cfactor, _ = normalize(image, xr.ones_like(strata), angles, roy2016_table(), REFERENCE, extrapolate=True)
    cfactor = np.asarray(cfactor.values)
    splits = {"in sample": [(everywhere, everywhere)],
              "checkerboard": [(black, ~black), (~black, black)],
              "by day (odd/even)": [(odd, ~odd), (~odd, odd)]}
    if not by_day:
        del splits["by day (odd/even)"]
    print(f"{args.data.name} composite, {image.sizes['y']} x {image.sizes['x']}, corrected to nadir at "
          f"sza {REFERENCE['sza']:g} deg; slope of pixel / {WINDOW}x{WINDOW} median against signed vza "
          f"[%/10 deg], 1-sigma clustered by {'composite day' if by_day else 'block'}")
    prior = None if args.prior_spread is None else ShapePrior("roy2016", args.prior_spread)
    measure = partial(slopes, signed=signed, groups=groups, day=day, wavelengths=wavelengths)
    for split, folds in splits.items():
        held_out = {levels: np.full(raw.shape, np.nan, dtype=np.float32) for levels in methods}
        for number, (fit_on, assess_on) in enumerate(folds):
            results = {"raw": measure(raw, assess_on=assess_on), "c-factor": measure(cfactor, assess_on=assess_on)}
            for levels in methods:
                corrected = fit_and_correct(image, angles, strata, fit_on, levels, prior)
                held_out[levels][:, assess_on] = corrected[:, assess_on]
                results[levels] = measure(corrected, assess_on=assess_on)
            report(f"{split}, fold {number}", results, methods)
        if len(folds) == 2:  # every pixel corrected by the fit of the fold that left it out
            results = {"raw": measure(raw, assess_on=everywhere), "c-factor": measure(cfactor, assess_on=everywhere),
                       **{levels: measure(held_out[levels], assess_on=everywhere) for levels in methods}}
            report(f"{split}, cross-fitted (each pixel corrected by the other fold's fit)", results, methods)
    print(f"\n{time.perf_counter() - start:.0f} s")


def report(title: str, results: dict[str, dict[str, tuple[float, float]]], methods: list[str]) -> None:
    """Print the slopes of every method and whether the fitted ones meet the goals."""
    print(f"\n{title}:")
    print(f"  {'group band':16s}" + "".join(f"{method:>16s}" for method in results))
    for key in results["raw"]:
        print(f"  {key:16s}" + "".join(f"{results[m][key][0]:+8.2f}±{results[m][key][1]:<6.2f}" for m in results))
    limit = worst(results["c-factor"])
    print(f"  c-factor: worst {limit:.2f}; p(slopes | none left) {chance(results['c-factor']):.2g}")
    for levels in methods:
        value = worst(results[levels])
        met = value <= GOAL_WORST and value <= GOAL_RATIO * limit
        median, high = noise_floor(results[levels])
        print(f"  {levels}: worst {value:.2f} (goal <= {GOAL_WORST} and <= half the c-factor's "
              f"{limit:.2f}: {'met' if met else 'MISSED'}); raw {worst(results['raw']):.2f}; a perfect "
              f"correction's worst, from these 1-sigmas: {median:.2f} (90 %: {high:.2f}); p(slopes | none "
              f"left) {chance(results[levels]):.2g}")


if __name__ == "__main__":
    main()
