"""Topographic illumination correction: cosine, C, SCS and SCS+C (lazy, chunked).

A surface of slope s and aspect A under a sun at zenith sza receives the direct sunlight at the
incidence angle i (:func:`brdfcorr.correction.terrain.cos_incidence`); a reflectance computed for horizontal
irradiance (as image reflectance products are) is then too bright on slopes facing the sun and too
dark on those facing away. The corrections scale each pixel and band to a horizontal surface::

    cosine  (Teillet et al. 1982, eq. 4)      rho_h = rho_t * cos sza / cos i
    C       (Teillet et al. 1982, eq. 8)      rho_h = rho_t * (cos sza + C) / (cos i + C)
    SCS     (Gu & Gillespie 1998, eq. 8)      rho_h = rho_t * cos s cos sza / cos i
    SCS+C   (Soenen et al. 2005, eq. 9)       rho_h = rho_t * (cos s cos sza + C) / (cos i + C)

The cosine correction is exact for a Lambertian surface: it removes the illumination term, and
chained with :func:`brdfcorr.correction.normalize` given the same slope and aspect (the BRDF in the
surface's frame) it is exact for any surface whose model is known (``docs/terrain.md``). C and SCS+C
are the empirical corrections for when the BRDF is not modelled: C = b / m from the least-squares
line ``rho_t = m cos i + b`` of the image's pixels, per class and band (:func:`fit_c`).

Guard: a fit with fewer than ``min_pixels`` pixels, a slope ``m <= 0``, a coefficient of
determination R^2 below ``r2_min`` (default :data:`R2_MIN` = 0.1: cos i explains under 10 % of the
variance, the line says nothing about the illumination) or C outside ``(-min cos i, 10]`` is
rejected: that class and band are not corrected (factor 1), flagged ``topography_uncorrected``, and a
warning names them (the reason states the interval, e.g. ``C = -0.5 outside (-0.4226, 10]``). The
lower bound is what the correction needs: ``cos i + C`` must not vanish on a lit pixel, so C must
exceed -min(cos i) over the lit pixels (``cos i > cos_i_min``) of the class that entered the fit. A
C between that bound and 0 is applied: a Lambertian class fits C = 0 plus noise, negative about
half the time, and its near-zero C gives the cosine correction's values. Above 10 the correction
changes a pixel by under 10 % of the cosine correction's change. ``c_range`` (default
:data:`C_RANGE` = (-inf, 10]) gives the upper bound and may raise the lower one (its lower end,
inclusive, applies where it exceeds -min cos i). A lit pixel whose factor is not finite and positive
(possible only for C < 0: with a C table from another scene, ``cos i + C <= 0``, or
``cos sza + C <= 0`` where every pixel of the class is lit more steeply than flat ground) is not
corrected either and is flagged ``topography_uncorrected``.

QA layer: the correction's flags (:class:`brdfcorr.correction.qa.QA`), of which this step sets
``NODATA`` (NaN or +-inf in some band, angle, slope or aspect: output nodata there), ``NO_CLASS``
(C methods with a class map: class 0, NaN or its nodata: not corrected), ``TOPOGRAPHY_UNCORRECTED``
(the C fit of the pixel's class was rejected in some band, or its C gives the pixel no finite
positive factor: not corrected there), ``LIMITED`` (the
factor was clipped to the limits in at least one band) and ``FACING_AWAY`` (cos i <= ``cos_i_min``:
self-shadowed, no direct sunlight; output nodata).

References
----------
.. [1] P. M. Teillet, B. Guindon, D. G. Goodenough (1982): On the slope-aspect correction of
   multispectral scanner data. Can. J. Remote Sens. 8(2), 84-106.
.. [2] X. Gu, A. Gillespie (1998): Topographic normalization of Landsat TM images of forest based
   on subpixel sun-canopy-sensor geometry. Remote Sens. Environ. 64, 166-175.
.. [3] S. A. Soenen, D. R. Peddle, C. A. Coburn (2005): SCS+C: a modified sun-canopy-sensor
   topographic correction in forested terrain. IEEE Trans. Geosci. Remote Sens. 43(9), 2148-2159.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, NamedTuple

import dask
import dask.array as da
import numpy as np
import pandas as pd
import xarray as xr

from brdfcorr._arrays import cosd
from brdfcorr._entry import option
from brdfcorr.correction.blocks import no_class_mask, split_pairs
from brdfcorr.correction.checks import angle_statistics
from brdfcorr.correction.inputs import angle_layers, check_grid
from brdfcorr.correction.qa import QA, qa_attrs, set_flags
from brdfcorr.correction.terrain import cos_incidence
from brdfcorr.defaults import C_METHODS, DEFAULT_LIMITS, TOPOGRAPHIC_METHODS
from brdfcorr.errors import BrdfcorrWarning, InputError
from brdfcorr.io.angles import looks_like_radians
from brdfcorr.io.reflectance import declared_nodata, reflectance_factors, unpacked

__all__ = [
    "METHODS",
    "C_RANGE",
    "R2_MIN",
    "MIN_PIXELS",
    "Topographic",
    "fit_c",
    "topographic_correction",
    "topographic_factor",
]

Method = Literal["cosine", "c", "scs", "scs+c"]
METHODS: tuple[str, ...] = TOPOGRAPHIC_METHODS  # written once in brdfcorr.defaults (the command line's words)


#: Least coefficient of determination of an accepted C fit [-].
R2_MIN = 0.1
#: Accepted range of C [-], besides the bound C > -min(cos i) over the class's lit pixels that every
#: fit must meet (module docstring, "Guard"): no further lower bound, at most 10.
C_RANGE = (-np.inf, 10.0)
#: Least number of pixels of an accepted C fit.
MIN_PIXELS = 30


_TABLE_COLUMNS = ["class", "band", "wavelength", "n", "slope", "intercept", "r2", "c", "accepted", "reason"]
#: Columns of the per-class and band statistics of the fit: the sums n, x, y, xx, xy, yy (x = cos i,
#: y = reflectance; added up over blocks) and the least x (combined by minimum).
_N_SUMS = 6
_MIN_X = 6


class Topographic(NamedTuple):
    """Result of :func:`topographic_correction`."""

    reflectance: xr.DataArray
    qa: xr.DataArray
    c_table: pd.DataFrame | None


def topographic_factor(method: str, cos_i, cos_sza, cos_slope=None, c=None):
    """The topographic correction factor rho_h / rho_t [-] (module docstring equations).

    Parameters
    ----------
    method : {"cosine", "c", "scs", "scs+c"}
    cos_i : array-like
        Cosine of the solar incidence angle on the surface [-] (:func:`brdfcorr.correction.terrain.cos_incidence`).
    cos_sza : array-like
        Cosine of the solar zenith [-].
    cos_slope : array-like, optional
        Cosine of the slope [-]; required by "scs" and "scs+c".
    c : array-like, optional
        The C coefficient [-]; required by "c" and "scs+c".

    Returns
    -------
    array-like
        ``cos sza / cos i`` (cosine, Teillet et al. 1982 eq. 4), ``(cos sza + C) / (cos i + C)``
        (C, eq. 8), ``cos s cos sza / cos i`` (SCS, Gu & Gillespie 1998 eq. 8),
        ``(cos s cos sza + C) / (cos i + C)`` (SCS+C, Soenen et al. 2005 eq. 9).
    """
    if method not in METHODS:
        raise InputError(f"topographic method must be one of {', '.join(METHODS)}, got {method!r}")
    if method in ("scs", "scs+c") and cos_slope is None:
        raise InputError(f"topographic method {method!r} needs cos_slope")
    if method in C_METHODS and c is None:
        raise InputError(f"topographic method {method!r} needs the C coefficient")
    numerator = cos_sza if method in ("cosine", "c") else cos_slope * cos_sza
    if method in C_METHODS:
        return (numerator + c) / (cos_i + c)
    return numerator / cos_i


# --- the C fit -------------------------------------------------------------------------------------

def _class_index(classes, class_ids: np.ndarray, class_nodata):
    """Index into ``class_ids`` per pixel and whether the pixel belongs to one of them."""
    if classes is None:
        return None, None
    classes = np.asarray(classes).reshape(-1)
    no_class = no_class_mask(classes, class_nodata)
    index = np.clip(np.searchsorted(class_ids, classes), 0, max(class_ids.size - 1, 0))
    member = ~no_class & (class_ids[index] == classes) if class_ids.size else np.zeros(classes.shape, bool)
    return index, member


def _block_sums(reflectance, cos_i, classes, class_ids, class_nodata, cos_i_min):
    """Sums (n, x, y, xx, xy, yy) and the least x per class and band of one block: array (class,
    band, 7) (x = cos i of the lit pixels, y = reflectance; the least x is +inf without pixels)."""
    n_bands = reflectance.shape[0]
    cube = np.asarray(reflectance, dtype=np.float64).reshape(n_bands, -1)
    x = np.asarray(cos_i, dtype=np.float64).reshape(-1)
    n_classes = max(len(class_ids), 1)
    index, member = _class_index(classes, class_ids, class_nodata)
    if index is None:
        index, member = np.zeros(x.shape, dtype=np.intp), np.ones(x.shape, bool)
    with np.errstate(invalid="ignore"):
        lit = member & np.isfinite(x) & (x > cos_i_min)
    sums = np.zeros((n_classes, n_bands, _N_SUMS + 1))
    sums[:, :, _MIN_X] = np.inf
    for band in range(n_bands):
        y = cube[band]
        use = lit & np.isfinite(y)
        where, xs, ys = index[use], x[use], y[use]
        for k, weights in enumerate((None, xs, ys, xs * xs, xs * ys, ys * ys)):
            sums[:, band, k] = np.bincount(where, weights=weights, minlength=n_classes)
        np.minimum.at(sums[:, band, _MIN_X], where, xs)
    return sums


def _fit_row(sums: np.ndarray, r2_min: float, c_range: tuple[float, float], min_pixels: int) -> dict:
    n, sx, sy, sxx, sxy, syy, min_cos_i = sums
    row: dict[str, Any] = dict(n=int(n), slope=np.nan, intercept=np.nan, r2=np.nan, c=np.nan)
    if n < min_pixels:
        return {**row, "accepted": False, "reason": f"{int(n)} pixels < {min_pixels}"}
    var_x, var_y, cov = sxx - sx * sx / n, syy - sy * sy / n, sxy - sx * sy / n
    if var_x <= 0:
        return {**row, "accepted": False, "reason": "cos i does not vary"}
    slope = cov / var_x
    intercept = (sy - slope * sx) / n
    r2 = cov * cov / (var_x * var_y) if var_y > 0 else 0.0
    c = intercept / slope if slope != 0 else np.inf
    row.update(slope=slope, intercept=intercept, r2=r2, c=c)
    if slope <= 0:
        return {**row, "accepted": False, "reason": f"slope m = {slope:.3g} <= 0"}
    if r2 < r2_min:
        return {**row, "accepted": False, "reason": f"R2 = {r2:.3f} < {r2_min:g}"}
    # cos i + C > 0 on every lit pixel of the fit: C > -min(cos i) (open bound), and within c_range.
    if c_range[0] > -min_cos_i:
        inside, lower = c_range[0] <= c, f"[{c_range[0]:g}"
    else:
        inside, lower = c > -min_cos_i, f"({-min_cos_i:.4g}"
    if not (inside and c <= c_range[1]):
        return {**row, "accepted": False, "reason": f"C = {c:.3g} outside {lower}, {c_range[1]:g}]"}
    return {**row, "accepted": True, "reason": ""}


def _class_ids(classes, class_nodata) -> np.ndarray:
    values = classes.data
    unique = da.unique(values).compute() if isinstance(values, da.Array) else np.unique(values)
    return unique[~no_class_mask(unique, class_nodata)]


def fit_c(
    reflectance,
    cos_i,
    classes=None,
    *,
    class_nodata: float | None = None,
    r2_min: float = R2_MIN,
    c_range: tuple[float, float] = C_RANGE,
    min_pixels: int = MIN_PIXELS,
    cos_i_min: float = 0.0,
) -> pd.DataFrame:
    """Fit the C coefficient per class and band: least squares of reflectance on cos i.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x)
        Reflectance (any units); NaN and +-inf are left out. numpy or dask backed (read once).
    cos_i : xarray.DataArray (y, x)
        Cosine of the solar incidence angle [-] (:func:`brdfcorr.correction.terrain.cos_incidence`).
    classes : xarray.DataArray (y, x), optional
        Class map; 0, NaN and ``class_nodata`` are no class and left out. Without it all pixels are
        one class, reported as class 0.
    r2_min : float, default :data:`R2_MIN`
        Least coefficient of determination of an accepted fit [-].
    c_range : (float, float), default :data:`C_RANGE`
        Accepted range of C [-] (both ends inclusive), on top of the bound every fit must meet,
        C > -min(cos i) over its lit pixels (module docstring, "Guard"); the default (-inf, 10]
        adds only the upper bound.
    min_pixels : int, default :data:`MIN_PIXELS`
        Least number of pixels of an accepted fit.
    cos_i_min : float, default 0
        Only lit pixels, ``cos i > cos_i_min``, enter the fit.

    Returns
    -------
    pandas.DataFrame
        One row per class and band: ``class``, ``band`` (0-based), ``wavelength`` [nm] (NaN
        without a ``wavelength`` coord), ``n``, ``slope`` m and ``intercept`` b of
        ``rho = m cos i + b``, ``r2``, ``c`` = b / m (Teillet et al. 1982, eq. 7), ``accepted``
        and, when rejected, the ``reason`` (module docstring, "Guard").
    """
    reflectance = _as_cube(reflectance)
    cos_i = _layer(reflectance, "cos_i", cos_i)
    if classes is not None:
        classes = _layer(reflectance, "classes", classes)
        class_ids = _class_ids(classes, class_nodata)
    else:
        class_ids = np.array([0])
    arrays = [reflectance.data, cos_i.data] + ([classes.data] if classes is not None else [])
    options = dict(class_ids=class_ids, class_nodata=class_nodata, cos_i_min=float(cos_i_min))
    if any(isinstance(a, da.Array) for a in arrays):
        sums = _dask_sums(arrays, options)
    else:
        sums = _block_sums(arrays[0], arrays[1], arrays[2] if classes is not None else None, **options)
    wavelengths = (reflectance["wavelength"].values if "wavelength" in reflectance.coords
                   else np.full(reflectance.shape[0], np.nan))
    rows = []
    for k, class_id in enumerate(class_ids.tolist()):
        for band in range(reflectance.shape[0]):
            row = _fit_row(sums[k, band], float(r2_min), (float(c_range[0]), float(c_range[1])), int(min_pixels))
            rows.append({"class": class_id, "band": band, "wavelength": float(wavelengths[band]), **row})
    return pd.DataFrame(rows, columns=_TABLE_COLUMNS)


def _dask_sums(arrays, options) -> np.ndarray:
    """The per-block sums of :func:`_block_sums`, added up in one pass over the image."""
    cube = arrays[0] if isinstance(arrays[0], da.Array) else da.from_array(arrays[0], chunks="auto")
    layers = [da.asarray(a).rechunk(cube.chunks[1:]).to_delayed() for a in arrays[1:]]
    blocks = cube.to_delayed()
    band_starts = np.cumsum((0,) + cube.chunks[0])
    parts = []
    for b, y, x in np.ndindex(blocks.shape):
        parts.append((b, dask.delayed(_block_sums)(
            blocks[b, y, x], layers[0][y, x], layers[1][y, x] if len(layers) > 1 else None, **options)))
    computed = dask.compute(*(part for _, part in parts))
    total = np.zeros((max(len(options["class_ids"]), 1), cube.shape[0], _N_SUMS + 1))
    total[:, :, _MIN_X] = np.inf
    for (b, _), sums in zip(parts, computed):
        bands = slice(band_starts[b], band_starts[b + 1])
        total[:, bands, :_N_SUMS] += sums[:, :, :_N_SUMS]
        total[:, bands, _MIN_X] = np.minimum(total[:, bands, _MIN_X], sums[:, :, _MIN_X])
    return total


# --- the correction --------------------------------------------------------------------------------

@dataclass(frozen=True)
class _StepSettings:
    """What every block of the topographic step needs besides its arrays: the method, the C
    lookup (class ids, C per class and band, accepted fits), the class map's nodata, the limits,
    the self-shadowing threshold and the output dtype."""

    method: str
    class_ids: np.ndarray
    c_matrix: np.ndarray
    accepted: np.ndarray
    class_nodata: float | None
    limits: tuple[float, float] | None
    cos_i_min: float
    out_dtype: np.dtype


def _correct_block(reflectance, band_index, cos_i, cos_sza, cos_slope, classes=None, *, settings: _StepSettings):
    """Correct one (band, y, x) block; returns (corrected block, QA block (1, y, x))."""
    method, class_ids, c_matrix, accepted = settings.method, settings.class_ids, settings.c_matrix, settings.accepted
    class_nodata, limits, cos_i_min, out_dtype = (settings.class_nodata, settings.limits, settings.cos_i_min,
                                                  settings.out_dtype)
    n_bands, ny, nx = reflectance.shape
    cube = reflectance.reshape(n_bands, -1)
    ci, cz, cs = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (cos_i, cos_sza, cos_slope))
    qa = np.zeros(ci.size, dtype=np.uint8)
    finite = np.isfinite(ci) & np.isfinite(cz) & np.isfinite(cs)
    set_flags(qa, ~finite, QA.NODATA)
    with np.errstate(invalid="ignore"):
        shadowed = finite & (ci <= cos_i_min)
    set_flags(qa, shadowed, QA.FACING_AWAY)
    if cube.dtype.kind == "f":
        set_flags(qa, ~np.isfinite(cube).all(axis=0), QA.NODATA)
    index, member = None, np.ones(ci.size, bool)
    if method in C_METHODS:
        index, member = _class_index(classes, class_ids, class_nodata)
        if index is None:
            index, member = np.zeros(ci.size, dtype=np.intp), np.ones(ci.size, bool)
        else:
            set_flags(qa, ~member, QA.NO_CLASS)
    usable = finite & ~shadowed
    out = np.empty(cube.shape, dtype=out_dtype)
    with np.errstate(divide="ignore", invalid="ignore"):
        for position, band in enumerate(np.asarray(band_index).reshape(-1)):
            factor = np.ones(ci.size)
            if index is None:
                factor = topographic_factor(method, ci, cz, cs)
            else:
                ok = member & accepted[index, band]
                factor[ok] = topographic_factor(method, ci[ok], cz[ok], cs[ok], c_matrix[index[ok], band])
                # Only a C < 0 (e.g. from a C table of another scene) can give a lit pixel a factor that
                # is not finite and positive (cos i + C <= 0, or numerator + C <= 0): not corrected there.
                invalid = ok & usable & ~(np.isfinite(factor) & (factor > 0))
                factor[invalid] = 1.0
                set_flags(qa, (member & ~ok) | invalid, QA.TOPOGRAPHY_UNCORRECTED)
            if limits is not None:
                set_flags(qa, usable & ((factor < limits[0]) | (factor > limits[1])), QA.LIMITED)
                factor = np.clip(factor, *limits)
            factor[~usable] = np.nan
            np.multiply(cube[position], factor, out=out[position], casting="unsafe")
    return out.reshape(n_bands, ny, nx), qa.reshape(1, ny, nx)


def _as_cube(reflectance) -> xr.DataArray:
    """The reflectance as a (band, y, x) DataArray of its values: integer counts that carry a scale
    scaled with it and its offset (an offset left in would change C and the cosine correction
    alike), a declared float nodata as NaN (:func:`~brdfcorr.io.reflectance.reflectance_factors`);
    counts without a scale are taken in their own units."""
    if not isinstance(reflectance, xr.DataArray):
        array = reflectance if isinstance(reflectance, da.Array) else np.asarray(reflectance)
        reflectance = xr.DataArray(array, dims=("band", "y", "x"), name="reflectance")
    if reflectance.ndim != 3:
        raise InputError(f"reflectance must be 3-D (band, y, x), got dims {reflectance.dims}")
    return reflectance_factors(reflectance, unscaled_counts=True)


def _layer(reflectance: xr.DataArray, name: str, value) -> xr.DataArray:
    """A (y, x) layer on the reflectance's grid (numbers broadcast); GridMismatchError otherwise.
    Packed values (int16 hundredths of a degree with a ``scale_factor``) of any layer but the class
    map are unpacked (:func:`brdfcorr.io.reflectance.unpacked`)."""
    spatial = reflectance.dims[1:]
    if not isinstance(value, xr.DataArray):
        array = value if isinstance(value, da.Array) else np.asarray(value)
        if array.ndim == 0:
            array = np.broadcast_to(array, reflectance.shape[1:])
        if array.ndim != 2:
            raise InputError(f"{name} must be 2-D (y, x), got shape {array.shape}")
        value = xr.DataArray(array, dims=spatial, name=name)
    # Same checks as the BRDF step (shape, coordinates, CRS); then positional: the output takes
    # the reflectance's coordinates.
    value = check_grid(reflectance, name, value)
    value = value if name == "classes" else unpacked(value, name)
    return value.drop_vars(list(value.coords))


def _refuse_radians(*pairs: Mapping[str, xr.DataArray]) -> None:
    """Refuse (zenith, azimuth) pairs of numpy layers (sza and saa, slope and aspect) that can only
    be radians (:func:`brdfcorr.io.angles.looks_like_radians`: every zenith below pi/2 and every
    azimuth below 2 pi); dask layers are not read for it."""
    for pair in pairs:
        if any(isinstance(layer.data, da.Array) for layer in pair.values()):
            continue
        statistics = [angle_statistics(np.asarray(layer.values, dtype=float)) for layer in pair.values()]
        ranges = {name: found[0] for name, found in zip(("sza", "saa"), statistics)}
        if looks_like_radians(ranges, {name: found[1][0] for name, found in zip(("sza", "saa"), statistics)}):
            found = ", ".join(f"{name} {low:.3g}..{high:.3g}" for name, ((low, high), _) in zip(pair, statistics))
            raise InputError(f"angles: {' and '.join(pair)} look like radians ({found}); brdfcorr needs degrees"
                             f"{option('degrees')}")


def _c_lookup(c_table: pd.DataFrame, n_bands: int):
    """Class ids, C (class, band) and accepted (class, band) arrays from a C table."""
    missing = {"class", "band", "c", "accepted"} - set(c_table.columns)
    if missing:
        raise InputError(f"C table lacks the column(s) {sorted(missing)}")
    class_ids = np.unique(c_table["class"].to_numpy())
    c_matrix = np.zeros((class_ids.size, n_bands))
    accepted = np.zeros((class_ids.size, n_bands), dtype=bool)
    bands = c_table["band"].to_numpy().astype(int)
    if bands.size and not ((bands >= 0) & (bands < n_bands)).all():
        raise InputError(f"C table: bands {sorted(set(bands[(bands < 0) | (bands >= n_bands)]))} outside "
                         f"the image's {n_bands} bands")
    rows = np.searchsorted(class_ids, c_table["class"].to_numpy())
    c_matrix[rows, bands] = c_table["c"].to_numpy(dtype=np.float64)
    accepted[rows, bands] = c_table["accepted"].to_numpy(dtype=bool) & np.isfinite(c_matrix[rows, bands])
    return class_ids, c_matrix, accepted


def _check_c_classes(class_ids: np.ndarray, with_classes: bool) -> None:
    """Refuse a C table whose classes the correction cannot tell apart: C per class without a
    class map (every pixel would take the first class's C), or one C for the whole image (class 0)
    with a class map (no pixel would find its class)."""
    per_class = class_ids[class_ids != 0]
    if not with_classes and per_class.size:
        raise InputError(f"the C table holds C per class ({', '.join(map(str, per_class[:5].tolist()))}): give the "
                         "class map it was fitted with (classes=)")
    if with_classes and not per_class.size:
        raise InputError("the C table was fitted without a class map (class 0): apply it without classes")


def _warn_rejected(table: pd.DataFrame) -> None:
    rejected = table[~table["accepted"].astype(bool)]
    if len(rejected):
        listed = "; ".join(f"class {r['class']} band {r['band'] + 1}: {r['reason']}"  # bands from 1, as everywhere
                           for _, r in rejected.head(5).iterrows())
        more = f" (and {len(rejected) - 5} more)" if len(rejected) > 5 else ""
        warnings.warn(f"topographic C fit rejected for {len(rejected)} class/band(s), not corrected there: "
                      f"{listed}{more}", BrdfcorrWarning, stacklevel=3)


def topographic_correction(
    reflectance,
    angles,
    *,
    method: Method = "scs+c",
    classes=None,
    c_table: pd.DataFrame | None = None,
    limits: tuple[float, float] | None = DEFAULT_LIMITS,
    r2_min: float = R2_MIN,
    c_range: tuple[float, float] = C_RANGE,
    min_pixels: int = MIN_PIXELS,
    cos_i_min: float = 0.0,
) -> Topographic:
    """Correct a reflectance cube for the illumination of sloped terrain.

    Parameters
    ----------
    reflectance : xarray.DataArray (band, y, x)
        Reflectance for horizontal irradiance (any units; kept). numpy or dask backed.
    angles : xarray.Dataset or mapping of str to xarray.DataArray (y, x) or number
        ``sza`` and ``saa``, solar zenith and azimuth (pixel towards the sun, clockwise from north)
        [deg], and ``slope`` and ``aspect``, the surface slope [deg] and the azimuth it faces
        (downslope, clockwise from north) [deg] (:func:`brdfcorr.correction.terrain.slope_aspect`,
        an ``obs_ort`` file's bands). Other variables are not used.
    method : {"cosine", "c", "scs", "scs+c"}, default "scs+c"
        The correction (module docstring). "cosine" is the one to chain with the BRDF correction
        in the surface's frame (``docs/terrain.md``).
    classes : xarray.DataArray (y, x), optional
        Class map: C is fitted per class and band; without it, one C per band for the whole image.
        Its nodata (``classes.rio.nodata``, else ``_FillValue``), 0 and NaN mean "no class".
    c_table : pandas.DataFrame, optional
        C coefficients to use (the table :func:`fit_c` returns, e.g. from another scene), with
        the class map it was fitted with (C per class) or without one (class 0: one C per band);
        by default fitted on this image (which reads it once; the correction itself stays lazy).
    limits : (float, float) or None, default (0.2, 5)
        The factor is clipped to this range [-]; clipped pixels are flagged ``limited``.
    r2_min, c_range, min_pixels, cos_i_min :
        The fit's guard (:func:`fit_c`); ``cos_i_min`` also marks the self-shadowed pixels
        (``cos i <= cos_i_min``, output nodata).

    Returns
    -------
    Topographic
        ``(reflectance, qa, c_table)``: the corrected cube (the input's dims, coords, attrs and
        chunks; lazy for dask input), the QA layer (y, x) of uint8 flags (module docstring) and the
        C table used (None for "cosine" and "scs").

    Warns
    -----
    BrdfcorrWarning
        Some class/band C fits were rejected (they are not corrected and flagged).
    """
    if method not in METHODS:
        raise InputError(f"topographic method must be one of {', '.join(METHODS)}, got {method!r}")
    if limits is not None:
        limits = (float(limits[0]), float(limits[1]))
        if not (0 < limits[0] <= 1 <= limits[1] < np.inf):
            raise InputError(f"factor limits {limits} must satisfy 0 < lower <= 1 <= upper < inf")
    reflectance = _as_cube(reflectance)
    sza, saa, slope, aspect = (_layer(reflectance, name, layer)
                               for name, layer in angle_layers(angles, ("sza", "saa", "slope", "aspect")).items())
    _refuse_radians({"sza": sza, "saa": saa}, {"slope": slope, "aspect": aspect})
    cos_i = cos_incidence(sza, saa, slope, aspect)
    class_layer = _layer(reflectance, "classes", classes) if classes is not None else None
    class_nodata = declared_nodata(classes) if isinstance(classes, xr.DataArray) else None
    n_bands = reflectance.shape[0]
    lookup: tuple = (np.array([0]), np.zeros((1, n_bands)), np.zeros((1, n_bands), bool))
    if method in C_METHODS:
        if c_table is None:
            c_table = fit_c(reflectance, cos_i, class_layer, class_nodata=class_nodata, r2_min=r2_min,
                            c_range=c_range, min_pixels=min_pixels, cos_i_min=cos_i_min)
        _warn_rejected(c_table)
        lookup = _c_lookup(c_table, n_bands)
        _check_c_classes(lookup[0], class_layer is not None)
    else:
        c_table = None
    out_dtype = np.result_type(reflectance.dtype, np.float32)
    settings = _StepSettings(method, lookup[0], lookup[1], lookup[2], class_nodata, limits, float(cos_i_min),
                             out_dtype)
    layers = [cos_i.data, cosd(sza.data), cosd(slope.data)]
    if class_layer is not None and method in C_METHODS:
        layers.append(class_layer.data)
    if any(isinstance(a, da.Array) for a in [reflectance.data, *layers]):
        corrected, qa = _correct_dask(reflectance.data, layers, settings)
    else:
        corrected, qa = _correct_block(reflectance.data, np.arange(n_bands), *layers, settings=settings)
        qa = qa[0]
    corrected = xr.DataArray(corrected, dims=reflectance.dims, coords=reflectance.coords,
                             attrs={**reflectance.attrs, "topographic_correction": method}, name=reflectance.name)
    band_dim = reflectance.dims[0]
    spatial_coords = {k: v for k, v in reflectance.coords.items() if band_dim not in v.dims}
    qa = xr.DataArray(qa, dims=reflectance.dims[1:], coords=spatial_coords, name="topographic_qa",
                      attrs=qa_attrs("topographic correction quality flags"))
    return Topographic(corrected, qa, c_table)


def _correct_dask(cube, layers: Sequence, settings: _StepSettings):
    if not isinstance(cube, da.Array):
        cube = da.from_array(cube, chunks="auto")
    spatial = cube.chunks[1:]
    layers = [da.asarray(a).rechunk(spatial) for a in layers]
    band_index = da.arange(cube.shape[0], chunks=(cube.chunks[0],))
    pairs = da.blockwise(
        _correct_block, "byx", cube, "byx", band_index, "b",
        *(item for layer in layers for item in (layer, "yx")),
        meta=np.empty((0, 0, 0), dtype=settings.out_dtype), settings=settings,
    )
    return split_pairs(pairs, settings.out_dtype)
