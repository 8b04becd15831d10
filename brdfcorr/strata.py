"""Class maps for per-class BRDF models: NDVI strata from the image itself (as FlexBRDF/HyTools
bin NDVI), or a land-cover map brought onto the image grid with its codes remapped to table ids.

All functions are lazy on dask input (only :func:`ndvi_strata` with ``percentiles`` reads the image
once, for its edges) and keep the x/y coords and CRS/transform of their input. Class maps are
integer; id 0 means "no class" (left uncorrected by :mod:`brdfcorr.correction`) and is the nodata of
the maps made here.

References: Queally, N. et al. (2022), FlexBRDF, JGR Biogeosciences 127, e2021JG006622. Zhu, Z.
and Woodcock, C. E. (2012), Fmask, Remote Sensing of Environment 118, 83-94. Zanaga, D. et al.
(2021), ESA WorldCover 10 m 2020 v100, doi:10.5281/zenodo.5571936 (legend kept in 2021 v200).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import dask
import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers the .rio accessor)
import xarray as xr
from affine import Affine
from rasterio.enums import Resampling
from rasterio.transform import array_bounds
from rasterio.warp import transform_bounds

from brdfcorr._arrays import is_lazy
from brdfcorr._entry import option
from brdfcorr.defaults import DEFAULT_EDGES, NIR_RANGE, RED_RANGE
from brdfcorr.errors import InputError
from brdfcorr.io.reflectance import reflectance_factors
from brdfcorr.io.scale_check import checked_factors
from brdfcorr.io.wavelengths import with_wavelengths

__all__ = [
    "ndvi", "ndvi_strata", "NdviStrata", "remap_classes", "align_class_map", "WORLDCOVER_CODES",
    "RED_RANGE", "NIR_RANGE", "DEFAULT_EDGES", "WATER_TESTS", "SHADOW_REFLECTANCE",
]

#: Water tests, OR-ed: (NDVI below, NIR reflectance below) pairs; Fmask's water test (Zhu and
#: Woodcock 2012, eq. 5): NDVI < 0.01 and NIR < 0.11, or NDVI < 0.1 and NIR < 0.05.
WATER_TESTS = ((0.01, 0.11), (0.1, 0.05))
#: Shadow test: (red + NIR) / 2 below this reflectance. A heuristic (no standard value): skylight
#: alone (about a tenth of the clear-sky red/NIR irradiance) takes land at 0.1-0.3 to ~0.01-0.03.
SHADOW_REFLECTANCE = 0.03
#: ESA WorldCover 10 m 2020 (v100) / 2021 (v200) legend, code -> class (PUM); 0 is its nodata.
WORLDCOVER_CODES = {
    10: "Tree cover", 20: "Shrubland", 30: "Grassland", 40: "Cropland", 50: "Built-up",
    60: "Bare / sparse vegetation", 70: "Snow and ice", 80: "Permanent water bodies",
    90: "Herbaceous wetland", 95: "Mangroves", 100: "Moss and lichen",
}
# Percentile edges come from a histogram of NDVI over [-1, 1] in bins of 1e-4.
_HISTOGRAM_BINS = 20000


def _band_mean(image: xr.DataArray, span: Sequence[float], role: str) -> xr.DataArray:
    """Mean reflectance [1] of the bands whose centre lies in ``span`` [nm] (ends included), in
    float64: an NDVI on a bin edge in float32 arithmetic may fall below it."""
    if image.ndim != 3:
        raise InputError(f"the image must be (band, y, x); it has dims {image.dims}")
    image = with_wavelengths(image)
    if "wavelength" not in image.coords:
        source = image.encoding.get("source") or image.attrs.get("source") or "the image"
        raise InputError(f"{source}: no band centres [nm] in its tags, band descriptions or header; give them "
                         f"({option('wavelengths')})")
    low, high = (float(v) for v in span)
    wavelengths = np.asarray(image.coords["wavelength"].values, dtype=float)
    selected = np.flatnonzero((wavelengths >= low) & (wavelengths <= high))
    if selected.size == 0:
        raise InputError(f"no band of the image lies in the {role} range {low:g}-{high:g} nm "
                         f"(its bands span {wavelengths.min():g}-{wavelengths.max():g} nm)")
    band_dim = image.coords["wavelength"].dims[0]
    return image.isel({band_dim: selected}).astype(np.float64).mean(band_dim, skipna=False, keep_attrs=False)


def _normalized_difference(red_mean, nir_mean, red, nir) -> xr.DataArray:
    total = nir_mean + red_mean
    index = (nir_mean - red_mean) / total.where(total != 0)  # NaN, not +-inf, where nir + red = 0
    index.name = "ndvi"
    index.attrs = {"units": "1", "long_name": "normalized difference vegetation index",
                   "red_range_nm": f"{red[0]:g}-{red[1]:g}", "nir_range_nm": f"{nir[0]:g}-{nir[1]:g}"}
    return index


def ndvi(image: xr.DataArray, red: Sequence[float] = RED_RANGE, nir: Sequence[float] = NIR_RANGE) -> xr.DataArray:
    """Normalized difference vegetation index of a reflectance image (lazy on dask input).

    Parameters
    ----------
    image : xarray.DataArray (band, y, x)
        Reflectance [1] with a ``wavelength`` coordinate [nm] (:func:`brdfcorr.io.open_image`), or
        integer counts with their ``scale_factor``/``add_offset``
        (:func:`brdfcorr.io.reflectance.reflectance_factors`: an offset left out changes NDVI).
    red, nir : (float, float)
        Wavelength ranges [nm], ends included; the bands in each range are averaged.

    Returns
    -------
    xarray.DataArray (y, x)
        NDVI [1]; NaN where a band used is NaN or where red + NIR = 0. Raises :class:`InputError`
        without a wavelength coordinate or with no band in a range (naming both spans).

    Notes
    -----
    NDVI = (NIR - red) / (NIR + red) (Rouse et al. 1974; Tucker 1979). Negative reflectances
    (noise over dark targets) can give values outside [-1, 1]; they are kept.
    """
    image = reflectance_factors(image)
    return _normalized_difference(_band_mean(image, red, "red"), _band_mean(image, nir, "NIR"), red, nir)


@dataclass(frozen=True)
class NdviStrata:
    """Result of :func:`ndvi_strata`: ``classes`` (y, x) uint8 (1..n NDVI bins, water and shadow
    ids, 0 = no class and nodata), the NDVI bin ``edges`` [1] and ``names``, a label per class id
    (``"ndvi_0.30_0.50"``, ``-inf``/``inf`` at the open ends, ``"water"``, ``"shadow"``)."""

    classes: xr.DataArray
    edges: tuple[float, ...]
    names: dict[int, str]


def _increasing(values, what: str, low: float = -np.inf, high: float = np.inf) -> np.ndarray:
    """1 to 254 (uint8 classes) strictly increasing values within (low, high)."""
    array = np.asarray(values, dtype=float)
    if array.ndim != 1 or not 0 < array.size < 255 or not np.all((array > low) & (array < high)) \
            or np.any(np.diff(array) <= 0):
        raise InputError(f"{what} must be 1 to 254 strictly increasing values in ({low:g}, {high:g}), "
                         f"got {tuple(np.atleast_1d(values))}")
    return array


def _percentile_edges(index: xr.DataArray, binned: xr.DataArray, percentiles) -> tuple[float, ...]:
    """NDVI edges at ``percentiles`` [%] of the pixels to be binned: one pass over the image."""
    q = _increasing(percentiles, "percentiles", 0.0, 100.0)
    # A histogram, not dask's percentile: dask merges per-chunk percentiles with equal weights,
    # which is biased when chunks hold different numbers of valid pixels. NaN is not counted.
    values = index.clip(-1.0, 1.0).where(binned).data
    xp = da if isinstance(values, da.Array) else np
    counts, bin_edges = xp.histogram(values, bins=_HISTOGRAM_BINS, range=(-1.0, 1.0))
    counts = np.asarray(dask.compute(counts)[0])
    cumulative = np.cumsum(counts)
    if cumulative[-1] == 0:
        raise InputError("no pixel left to compute NDVI percentile edges from (all nodata, water or shadow)")
    targets = q / 100.0 * cumulative[-1]  # inverse of the cumulative histogram, linear in a bin
    bin_of = np.searchsorted(cumulative, targets, side="left")
    below = np.where(bin_of > 0, cumulative[bin_of - 1], 0)
    edges = bin_edges[bin_of] + (targets - below) / counts[bin_of] * (bin_edges[1] - bin_edges[0])
    return tuple(float(v) for v in edges)


def _bin_names(edges: tuple[float, ...]) -> dict[int, str]:
    for decimals in range(2, 7):  # as few decimals as keep the edges apart
        text = [f"{round(edge, decimals) + 0.0:.{decimals}f}" for edge in edges]  # + 0.0: no "-0.00"
        if len(set(text)) == len(text):
            break
    bounds = ["-inf", *text, "inf"]
    return {k + 1: f"ndvi_{bounds[k]}_{bounds[k + 1]}" for k in range(len(edges) + 1)}


def _check_extra_ids(water_id: int, shadow_id: int, n_bins: int) -> None:
    for role, value in (("water_id", water_id), ("shadow_id", shadow_id)):
        if value != 0 and not n_bins < value <= 255:
            raise InputError(f"{role} {value} must be 0 (no class) or an id in {n_bins + 1}..255 "
                             f"(NDVI bins are 1..{n_bins})")
    if water_id != 0 and water_id == shadow_id:
        raise InputError(f"water_id and shadow_id are both {water_id}; give them different ids or 0")


def _masks(image: xr.DataArray, index, red_mean, nir_mean, water: Sequence[tuple[float, float]],
           shadow_reflectance: float | None) -> tuple:
    """The valid pixels (every band finite, NDVI defined), and among them water (any of the
    ``water`` tests (NDVI below, NIR reflectance below) passed) and shadow (not water, (red + NIR) / 2
    [1] below ``shadow_reflectance``; None: no shadow test)."""
    band_dim = image.coords["wavelength"].dims[0]
    valid = np.isfinite(image).all(band_dim) & np.isfinite(index)
    water_pairs = np.reshape(np.asarray(water, dtype=float), (-1, 2))  # one pair or a sequence of pairs
    water_test = xr.zeros_like(valid)
    for ndvi_below, nir_below in water_pairs:
        water_test = water_test | ((index < ndvi_below) & (nir_mean < nir_below))
    is_water = valid & water_test
    dark = -np.inf if shadow_reflectance is None else shadow_reflectance  # -inf: no shadow test
    return valid, is_water, valid & ~is_water & ((red_mean + nir_mean) / 2 < dark)


def _classified(index, edges: Sequence[float], masks: tuple, water_id: int, shadow_id: int) -> xr.DataArray:
    """The uint8 class map: the NDVI bin + 1 (left-closed bins, ``np.digitize``) of the binned pixels,
    ``water_id`` and ``shadow_id`` for water and shadow, 0 elsewhere (``masks``: binned, water, shadow)."""
    binned, is_water, is_shadow = masks
    bins = xr.apply_ufunc(np.digitize, index, kwargs={"bins": np.asarray(edges)}, dask="parallelized",
                          output_dtypes=[np.intp])
    # DataArray.where, not xr.where: xr.where(cond, scalar, array) drops the spatial_ref attrs.
    return (bins + 1).where(binned, 0).where(~is_water, water_id).where(~is_shadow, shadow_id).astype(np.uint8)


def _strata_attrs(edges: Sequence[float], percentiles: Sequence[float] | None, ranges: tuple, names: dict[int, str],
                  tests: dict[str, object]) -> dict[str, object]:
    """The attributes of :func:`ndvi_strata`'s class map (output tags): the binning, the red and NIR
    ranges [nm] (``ranges``), the water and shadow ``tests`` (:func:`_test_attrs`) and the class names."""
    red, nir = ranges
    attrs = {
        "long_name": "NDVI stratum (class id)", "ndvi_edges": ",".join(f"{edge:.6g}" for edge in edges),
        "strata": "ndvi_percentiles" if percentiles is not None else "ndvi_edges",
        "ndvi_bins": "left-closed: class k holds edges[k-2] <= ndvi < edges[k-1]",
        "red_range_nm": f"{red[0]:g}-{red[1]:g}", "nir_range_nm": f"{nir[0]:g}-{nir[1]:g}",
        **tests,
        "class_names": ";".join(f"{key}={value}" for key, value in sorted(names.items())),
    }
    if percentiles is not None:
        attrs["ndvi_percentiles"] = ",".join(f"{p:g}" for p in percentiles)
    return attrs


def _test_attrs(water: Sequence[tuple[float, float]], shadow_reflectance: float | None, water_id: int,
                shadow_id: int) -> dict[str, object]:
    """The water and shadow tests and ids of :func:`ndvi_strata`, as attributes of its class map."""
    return {
        "water_test": " or ".join(f"(ndvi < {a:g} and nir < {b:g})" for a, b in water) or "none",
        "shadow_test": "none" if shadow_reflectance is None else f"(red + nir) / 2 < {shadow_reflectance:g}",
        "water_id": int(water_id), "shadow_id": int(shadow_id),
    }


def ndvi_strata(image: xr.DataArray, *, edges: Sequence[float] | None = None,
                percentiles: Sequence[float] | None = None, red: Sequence[float] = RED_RANGE,
                nir: Sequence[float] = NIR_RANGE, water: Sequence[tuple[float, float]] = WATER_TESTS,
                shadow_reflectance: float | None = SHADOW_REFLECTANCE, water_id: int = 0,
                shadow_id: int = 0) -> NdviStrata:
    """A uint8 class map of NDVI bins, with nodata, water and shadow masked (lazy on dask input).

    Parameters
    ----------
    image : xarray.DataArray (band, y, x)
        Reflectance [1] with a ``wavelength`` coordinate [nm] (:func:`brdfcorr.io.open_image`), or
        integer counts with their ``scale_factor``/``add_offset``
        (:func:`brdfcorr.io.reflectance.reflectance_factors`). Its red and NIR means are checked
        for values that are no reflectance factors (:func:`brdfcorr.io.scale_check.checked_factors`,
        lazily, by each chunk): the water and shadow tests are in reflectance factors, so percent
        or counts read without their scale would misfire.
    edges : sequence of float, optional
        Fixed NDVI edges [1], strictly increasing: n edges give classes 1..n+1. Default :data:`DEFAULT_EDGES`
        unless ``percentiles`` is given.
    percentiles : sequence of float, optional
        Percentiles [%] of the scene's NDVI to use as edges instead (e.g. ``(20, 40, 60, 80)`` for five
        near-equal classes), over the pixels that are binned (not nodata, water or shadow). Finding them
        reads the image once.
    red, nir : (float, float)
        Wavelength ranges [nm] of :func:`ndvi`.
    water : sequence of (float, float)
        (NDVI below, NIR reflectance below) tests, OR-ed; a pixel passing one is water. Default
        :data:`WATER_TESTS` (Fmask, Zhu and Woodcock 2012 eq. 5); ``()`` masks no water.
    shadow_reflectance : float or None
        (red + NIR) / 2 [1] below which a pixel is shadow (:data:`SHADOW_REFLECTANCE`); None: no test.
    water_id, shadow_id : int
        Ids of water and shadow pixels: 0 (no class, left uncorrected; default) or above the bins.

    Returns
    -------
    NdviStrata
        ``classes`` with rio nodata 0 and attrs describing the binning (for output tags). Raises
        :class:`InputError` for both ``edges`` and ``percentiles``, bad edges, percentiles or ids.

    Notes
    -----
    Order of the tests: nodata (a non-finite value in any band, or an undefined NDVI) -> 0; water ->
    ``water_id``; shadow -> ``shadow_id``; else the NDVI bin. Bins are left-closed: class k holds
    ``edges[k-2] <= NDVI < edges[k-1]`` (``np.digitize``), class 1 everything below the first edge and
    class n+1 everything from the last edge up. FlexBRDF (HyTools) bins by percentiles as well, with
    right-closed bins ``(start, end]``.
    """
    if edges is not None and percentiles is not None:
        raise InputError("give NDVI edges or percentiles, not both")
    image = reflectance_factors(image)
    red_mean, nir_mean = (checked_factors(_band_mean(image, span, role), image)
                          for span, role in ((red, "red"), (nir, "NIR")))
    index = _normalized_difference(red_mean, nir_mean, red, nir)
    valid, is_water, is_shadow = _masks(image, index, red_mean, nir_mean, water, shadow_reflectance)
    binned = valid & ~is_water & ~is_shadow
    edges = _percentile_edges(index, binned, percentiles) if percentiles is not None else tuple(
        float(edge) for edge in _increasing(DEFAULT_EDGES if edges is None else edges, "NDVI edges"))
    _check_extra_ids(water_id, shadow_id, len(edges) + 1)
    classes = _classified(index, edges, (binned, is_water, is_shadow), water_id, shadow_id)
    names = _bin_names(edges)
    names.update({value: role for role, value in (("water", water_id), ("shadow", shadow_id)) if value})
    classes.name = "classes"
    classes.attrs = _strata_attrs(edges, percentiles, (red, nir), names,
                                  _test_attrs(water, shadow_reflectance, water_id, shadow_id))
    return NdviStrata(classes.rio.write_nodata(0), tuple(edges), names)


def _check_integer(classes: xr.DataArray) -> None:
    if classes.dtype.kind not in "iu":
        raise InputError(f"the class map has data type {classes.dtype}; it needs integer class ids")
    if classes.ndim != 2:
        raise InputError(f"the class map must be (y, x); it has dims {classes.dims}")


def _ids(values, role: str) -> np.ndarray:
    ids = np.asarray(values)
    if ids.dtype.kind not in "iu" or np.any(ids < 0) or np.any(ids > 65535):
        raise InputError(f"{role} must be integers in 0..65535, got {np.atleast_1d(values).tolist()}")
    return ids.astype(np.int64)


def _remap_block(codes, *, keys, values, default, nodata, dtype):
    position = np.minimum(np.searchsorted(keys, codes), keys.size - 1)
    found = keys[position] == codes
    remapped = np.where(found, values[position], np.where(codes == 0, 0, default))
    if nodata is not None:
        remapped[codes == nodata] = 0
    return remapped.astype(dtype)


def remap_classes(classes: xr.DataArray, lookup: Mapping[int, int], *, default: int = 0) -> xr.DataArray:
    """Map the codes of a class map to table ids with a lookup table (vectorised, lazy).

    Parameters
    ----------
    classes : xarray.DataArray (y, x), integer
        Land-cover codes (e.g. :data:`WORLDCOVER_CODES`), with its nodata in ``.rio.nodata``.
    lookup : mapping of int to int
        Code -> table id (0..65535; 0 = no class).
    default : int
        Id of codes not in ``lookup`` (default 0, no class). Code 0 not in ``lookup`` stays 0.

    Returns
    -------
    xarray.DataArray (y, x)
        Table ids, uint8 (uint16 when an id exceeds 255), the map's nodata -> 0, rio nodata 0.
        Raises :class:`InputError` for a non-integer map, an empty lookup, ids outside 0..65535.
    """
    _check_integer(classes)
    if not lookup:
        raise InputError("the class lookup is empty")
    keys = np.asarray(list(lookup))
    if keys.dtype.kind not in "iu":
        raise InputError(f"lookup codes must be integers, got {list(lookup)}")
    values, default = _ids(list(lookup.values()), "lookup ids"), int(_ids(default, "the default id"))
    order, dtype = np.argsort(keys), np.uint8 if max(values.max(), default) <= 255 else np.uint16
    remapped = xr.apply_ufunc(  # keep_attrs: keeps the spatial_ref attrs (CRS); the attrs are set below
        _remap_block, classes, dask="parallelized", output_dtypes=[dtype], keep_attrs=True,
        kwargs={"keys": keys.astype(np.int64)[order], "values": values[order], "default": default,
                "nodata": classes.rio.nodata, "dtype": dtype})
    remapped.name = "classes"
    remapped.attrs = {"long_name": "class id", "class_lookup_default": default,
                      "class_lookup": ",".join(f"{k}:{v}" for k, v in sorted(lookup.items()))}
    return remapped.rio.write_nodata(0)


def _warp_block(source: xr.DataArray, crs, transform: Affine, shape: tuple[int, int]) -> np.ndarray:
    """Nearest-neighbour warp of a class-map window onto one block of the target grid; the
    window's nodata and places it does not cover become 0."""
    warped = source.rio.reproject(crs, shape=shape, transform=transform, resampling=Resampling.nearest, nodata=0)
    values, nodata = np.asarray(warped.values), source.rio.nodata
    # GDAL's nearest-neighbour warp can copy source nodata values through: clear them here.
    return values if nodata is None else np.where(values == nodata, 0, values).astype(values.dtype)


def _aligned_block(classes: xr.DataArray, crs, transform: Affine, shape: tuple[int, int]) -> da.Array:
    """One block of the target grid, from the window of ``classes`` that covers it (plus a pixel)."""
    source_crs, source_transform = classes.rio.crs, classes.rio.transform()
    west, south, east, north = transform_bounds(crs, source_crs, *array_bounds(*shape, transform), densify_pts=21)
    cols, rows = zip(*(~source_transform * (x, y) for x in (west, east) for y in (south, north)))
    row0, row1 = max(math.floor(min(rows)) - 1, 0), min(math.ceil(max(rows)) + 1, classes.rio.height)
    col0, col1 = max(math.floor(min(cols)) - 1, 0), min(math.ceil(max(cols)) + 1, classes.rio.width)
    if row1 <= row0 or col1 <= col0:
        return da.zeros(shape, dtype=classes.dtype, chunks=shape)
    window = classes.isel({classes.rio.y_dim: slice(row0, row1), classes.rio.x_dim: slice(col0, col1)})
    window = window.rio.write_transform(source_transform * Affine.translation(col0, row0))
    block = dask.delayed(_warp_block, pure=True)(window, crs, transform, shape)
    return da.from_delayed(block, shape, dtype=classes.dtype)


def _check_overlap(classes: xr.DataArray, image: xr.DataArray) -> None:
    for role, layer in (("class map", classes), ("image", image)):
        if layer.rio.crs is None:
            raise InputError(f"the {role} has no CRS; write one (.rio.write_crs) to align the class map")
    west, south, east, north = transform_bounds(image.rio.crs, classes.rio.crs, *image.rio.bounds(), densify_pts=21)
    c_west, c_south, c_east, c_north = classes.rio.bounds()
    if west >= c_east or east <= c_west or south >= c_north or north <= c_south:
        raise InputError(f"the class map (bounds {c_west:g}, {c_south:g}, {c_east:g}, {c_north:g} in "
                         f"{classes.rio.crs}) does not overlap the image (bounds {west:g}, {south:g}, "
                         f"{east:g}, {north:g} in that CRS)")


#: Attributes of how a layer is stored, not of its classes.
_ENCODING = frozenset({"_FillValue", "scale_factor", "add_offset", "units", "long_name"})


def align_class_map(classes: xr.DataArray, image: xr.DataArray,
                    lookup: Mapping[int, int] | None = None) -> xr.DataArray:
    """Bring a class map on another grid or CRS onto the image grid by nearest neighbour (lazy).

    Parameters
    ----------
    classes : xarray.DataArray (y, x), integer
        Class map with a CRS (:func:`brdfcorr.io.open_classes`); its nodata means "no class".
    image : xarray.DataArray (..., y, x)
        Any layer on the target grid (the reflectance image); its y/x chunks become the result's.
    lookup : mapping of int to int, optional
        Code -> table id (:func:`remap_classes`), applied before resampling: a code 0 that is a
        class (MODIS land cover's water) stays apart from the 0 of places the map does not reach.

    Returns
    -------
    xarray.DataArray (y, x)
        The class map on the image grid: its dtype (or that of :func:`remap_classes`), 0 where it
        had nodata or does not reach, rio nodata 0, and attrs ``resampled_from_crs``,
        ``resampled_from_resolution`` and ``resampling`` (for output tags), besides the map's own
        (its class names, NDVI strata edges) where no ``lookup`` gives other ids. Raises
        :class:`InputError` for a non-integer map, a layer without a CRS, or no overlap at all.

    Notes
    -----
    rioxarray's ``reproject`` (which ``reproject_match`` calls; ``Resampling.nearest``) runs per
    block of the image grid on the window of the map covering the block, so a large map (a
    WorldCover tile) is never read whole. GDAL's approximate transformer (error up to 0.125 pixel)
    may give a pixel whose centre lies that close to a class boundary the neighbour's class.
    """
    _check_integer(classes)
    _check_overlap(classes, image)
    # What the map says of its classes (NDVI strata, class names) holds for its ids on any grid (an
    # aligned strata map was fitted as a map of other classes); a lookup gives other ids.
    remapped = {key: value for key, value in classes.attrs.items() if key not in _ENCODING}
    if lookup is not None:
        classes = remap_classes(classes, lookup)
        remapped = classes.attrs
    crs, transform = image.rio.crs, image.rio.transform()
    y_dim, x_dim = image.rio.y_dim, image.rio.x_dim
    chunks = image.chunksizes if image.chunks is not None else {y_dim: (image.rio.height,), x_dim: (image.rio.width,)}
    row_chunks, col_chunks = chunks[y_dim], chunks[x_dim]
    row_starts, col_starts = np.cumsum((0, *row_chunks)), np.cumsum((0, *col_chunks))
    data = da.block([
        [_aligned_block(classes, crs, transform * Affine.translation(col0, row0), (rows, cols))
         for col0, cols in zip(col_starts, col_chunks)]
        for row0, rows in zip(row_starts, row_chunks)
    ])
    if not (is_lazy(classes) or is_lazy(image)):
        data = data.compute()  # numpy in, numpy out
    aligned = xr.DataArray(data, dims=("y", "x"), name="classes",
                           coords={"y": image[y_dim].values, "x": image[x_dim].values})
    aligned = aligned.rio.write_crs(crs).rio.write_transform(transform).rio.write_nodata(0)
    (res_x, res_y), source_crs = classes.rio.resolution(), classes.rio.crs
    unit = "degree" if source_crs.is_geographic else (source_crs.linear_units or "unknown")
    aligned.attrs.update({**remapped, "long_name": "class id", "resampled_from_crs": source_crs.to_string(),
                          "resampled_from_resolution": f"{abs(res_x):g} x {abs(res_y):g} {unit}",
                          "resampling": "nearest"})
    return aligned
