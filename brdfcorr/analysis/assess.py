"""Did the BRDF correction work? Standard measures of the view-angle signal left in a scene.

A BRDF correction should take the view-angle dependence out of each class: the same roof, lawn or
field should have the same reflectance at either edge of a flight line, and two overlapping lines
should agree where they overlap. This module measures that, before and after a correction, per
class and band:

- :func:`assess_view_angles`: the least-squares slope of reflectance against the *signed* view
  zenith (:func:`signed_view_zenith`), absolute [1/deg] and relative [%/10 deg]; the ratio of the
  mean reflectance on the positive side of nadir to that on the negative side (forward/backward
  scattering, or right/left of the flight direction); and the across-track profile, the mean
  reflectance in bins of signed view zenith. One chunk-wise pass over the before and after cubes
  (dask: per-block sums, added in a tree, one compute).
- :func:`assess_overlap`: for two overlapping lines, the difference in the overlap (other line minus
  this one, on this line's grid via rioxarray's ``reproject_match``): RMSE, mean absolute
  difference and bias per band, before and after, with a histogram and a small map of the
  difference.
- :func:`leave_one_line_out`: for N lines, fit the parameters on N - 1 of them
  (:func:`brdfcorr.fit.fit_classes`), correct the held-out line with them
  (:func:`brdfcorr.normalize`) and assess it: a test of the correction on data its parameters
  never saw.

The files' versions (``brdfcorr assess``, ``brdfcorr assess-lines``, the chains' assess step) are
in :mod:`brdfcorr.workflow.assessment`.

The results are :class:`xarray.Dataset` objects with labelled dims (``stage``: before/after,
``band``, ``class``, ``vza_bin``) and units in their attrs; :func:`view_angle_report` and
:func:`overlap_report` turn them into plain dicts (NaN as ``None``, valid JSON). The figures are in
:mod:`brdfcorr.plot.assess`.
"""

from __future__ import annotations

import math
import operator
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

import dask
import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr
from rasterio.enums import Resampling

from brdfcorr._arrays import cosd, sind
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import InputError

__all__ = [
    "SIGN_CONVENTIONS",
    "signed_view_zenith",
    "assess_view_angles",
    "view_angle_report",
    "assess_overlap",
    "overlap_report",
    "Line",
    "HeldOutLine",
    "leave_one_line_out",
    "leave_one_line_out_report",
]

#: How the sign of the view zenith is chosen (:func:`signed_view_zenith`).
SIGN_CONVENTIONS = ("sun", "track")
#: The two stages compared.
STAGES = ("before", "after")
_SIGN_WORDS = {
    "sun": ("forward scattering: relative azimuth > 90 deg, the sensor opposite the sun",
            "backscattering: relative azimuth < 90 deg, the sensor on the sun's side"),
    "track": ("right of the flight direction (east of a line flown north)",
              "left of the flight direction (west of a line flown north)"),
}


# ----------------------------------------------------------------------------- signed zenith
def signed_view_zenith(vza, vaa, saa=None, *, by: Literal["sun", "track"] = "sun", heading: float | None = None):
    """The view zenith with a sign for the side of nadir the pixel is seen from.

    Parameters
    ----------
    vza : array-like
        View zenith [deg].
    vaa : array-like
        Azimuth of the direction from the pixel towards the sensor [deg], clockwise from north
        (``docs/conventions.md``).
    saa : array-like, optional
        Azimuth of the direction from the pixel towards the sun [deg]; needed for ``by="sun"``.
    by : {"sun", "track"}, default "sun"
        ``"sun"``: positive in the forward-scattering half (relative azimuth φ > 90°, the sensor
        opposite the sun: the side of the specular peak), negative in the backscattering half
        (φ < 90°: the side of the hot spot). ``"track"``: positive to the right of the flight
        direction ``heading`` (east of a line flown north), negative to its left.
    heading : float, optional
        Flight direction [deg], clockwise from north; needed for ``by="track"``.

    Returns
    -------
    array-like
        Signed view zenith [deg] in (-90, 90), of the kind of the inputs (numpy, dask or xarray).
        Pixels seen exactly perpendicular to the sun (φ = 90°) or to the track get 0.

    Notes
    -----
    ``"sun"``: θ_signed = θ_r · sign(−cos(saa − vaa)), since cos φ = cos(saa − vaa) < 0 exactly
    when φ > 90°. ``"track"``: θ_signed = θ_r · sign(sin(heading − vaa)); a pixel right of a
    northbound track sees the sensor to its west (vaa = 270°), sin(0° − 270°) = 1.
    """
    if by == "sun":
        if saa is None:
            raise InputError("the signed view zenith by the sun needs the solar azimuth (saa)")
        side = -cosd(saa - vaa)
    elif by == "track":
        if heading is None or not math.isfinite(heading):
            raise InputError("the signed view zenith by the track needs the flight direction (heading) in degrees")
        side = sind(heading - vaa)
    else:
        raise InputError(f"sign convention {by!r} is not one of {', '.join(SIGN_CONVENTIONS)}")
    return vza * np.sign(side)


# -------------------------------------------------------------------------- per-block sums
@dataclass
class _Sums:
    """Sums over valid pixels from which every statistic follows: K classes, B bands, 2 stages,
    M bins of signed view zenith, 2 sides (negative, positive)."""

    n: np.ndarray       # (K,) pixels
    s: np.ndarray       # (K,) sum of the signed zenith [deg]
    ss: np.ndarray      # (K,) sum of its square [deg^2]
    r: np.ndarray       # (2, B, K) sum of reflectance
    sr: np.ndarray      # (2, B, K) sum of signed zenith times reflectance
    bin_n: np.ndarray   # (K, M)
    bin_r: np.ndarray   # (2, B, K, M)
    side_n: np.ndarray  # (K, 2)
    side_r: np.ndarray  # (2, B, K, 2)

    def __add__(self, other: _Sums) -> _Sums:
        return _Sums(*(getattr(self, name) + getattr(other, name) for name in self.__dataclass_fields__))


def _class_index(classes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Index of each pixel's class in ``ids`` (sorted), -1 for other values (0, nodata, NaN)."""
    position = np.clip(np.searchsorted(ids, classes), 0, max(len(ids) - 1, 0))
    found = (ids[position] == classes) if len(ids) else np.zeros(classes.shape, bool)
    return np.where(found, position, -1)


def _block_sums(before, after, classes, vza, vaa, saa, *, ids, edges, by, heading, min_vza,
                flip_view_azimuth) -> _Sums:
    """:class:`_Sums` of one block: cubes (band, y, x), layers (y, x), numpy."""
    n_bands, n_classes, n_bins = before.shape[0], len(ids), len(edges) - 1
    vaa = vaa + 180.0 if flip_view_azimuth else vaa
    with np.errstate(invalid="ignore"):
        signed = signed_view_zenith(vza.astype(np.float64), vaa, saa, by=by, heading=heading)
        valid = (vza >= 0) & (vza < 90) & np.isfinite(signed)
    valid &= np.isfinite(before).all(axis=0) & np.isfinite(after).all(axis=0)
    index = _class_index(classes, ids)
    valid &= index >= 0
    k, s = index[valid], signed[valid]
    cubes = (before[:, valid].astype(np.float64), after[:, valid].astype(np.float64))
    bins = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_bins - 1)  # the last edge closes the last bin
    groups = k * n_bins + bins
    outer = np.abs(s) >= max(min_vza, np.finfo(float).tiny)  # 0 (nadir, or perpendicular) is on neither side
    sides = k[outer] * 2 + (s[outer] > 0)
    sums = _Sums(
        n=np.bincount(k, minlength=n_classes).astype(np.float64),
        s=np.bincount(k, weights=s, minlength=n_classes),
        ss=np.bincount(k, weights=s * s, minlength=n_classes),
        r=np.zeros((2, n_bands, n_classes)), sr=np.zeros((2, n_bands, n_classes)),
        bin_n=np.bincount(groups, minlength=n_classes * n_bins).astype(np.float64).reshape(n_classes, n_bins),
        bin_r=np.zeros((2, n_bands, n_classes, n_bins)),
        side_n=np.bincount(sides, minlength=n_classes * 2).astype(np.float64).reshape(n_classes, 2),
        side_r=np.zeros((2, n_bands, n_classes, 2)),
    )
    for stage, cube in enumerate(cubes):
        for band, values in enumerate(cube):
            sums.r[stage, band] = np.bincount(k, weights=values, minlength=n_classes)
            sums.sr[stage, band] = np.bincount(k, weights=s * values, minlength=n_classes)
            sums.bin_r[stage, band] = np.bincount(groups, weights=values,
                                                  minlength=n_classes * n_bins).reshape(n_classes, n_bins)
            sums.side_r[stage, band] = np.bincount(sides, weights=values[outer],
                                                   minlength=n_classes * 2).reshape(n_classes, 2)
    return sums


def _tree_sum(parts: list):
    """Add delayed partial sums pairwise (a tree: few partial results alive at once)."""
    while len(parts) > 1:
        parts = [dask.delayed(operator.add)(*parts[i:i + 2]) if i + 1 < len(parts) else parts[i]
                 for i in range(0, len(parts), 2)]
    return parts[0]


def _scene_sums(arrays: list, options: dict, compute: dict) -> _Sums:
    """:class:`_Sums` of whole arrays (before, after, classes, vza, vaa, saa): directly for numpy,
    per dask block and added in a tree otherwise (one compute; every block read once)."""
    if not any(isinstance(a, da.Array) for a in arrays):
        return _block_sums(*(None if a is None else np.asarray(a) for a in arrays), **options)
    cube = next(a for a in arrays[:2] if isinstance(a, da.Array))
    spatial = cube.chunks[1:]
    cubes = [da.asarray(a).rechunk((-1, *spatial)).to_delayed()[0] for a in arrays[:2]]
    layers = [None if a is None else da.asarray(a).rechunk(spatial).to_delayed() for a in arrays[2:]]
    block = dask.delayed(_block_sums, pure=True)
    parts = [
        block(cubes[0][i, j], cubes[1][i, j], *(None if layer is None else layer[i, j] for layer in layers),
              **options)
        for i in range(len(spatial[0])) for j in range(len(spatial[1]))
    ]
    (total,) = dask.compute(_tree_sum(parts), **compute)
    return total


def _present_ids(classes, nodata) -> np.ndarray:
    """The positive class ids of a class map (its nodata value excepted)."""
    data = classes.data if isinstance(classes, xr.DataArray) else classes
    values = da.unique(data).compute() if isinstance(data, da.Array) else np.unique(np.asarray(data))
    values = values[np.isfinite(values) & (values > 0)]
    return values[values != nodata] if nodata is not None else values


def _class_nodata(classes):
    if isinstance(classes, xr.DataArray):
        nodata = classes.rio.nodata
        return None if nodata is None or (isinstance(nodata, float) and math.isnan(nodata)) else nodata
    return None


def _divide(numerator, denominator):
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(denominator > 0, numerator / np.where(denominator > 0, denominator, 1.0), np.nan)


def _check_cubes(before, after) -> tuple[xr.DataArray, xr.DataArray]:
    cubes = []
    for name, cube in (("before", before), ("after", after)):
        if not isinstance(cube, xr.DataArray):
            cube = xr.DataArray(cube, dims=("band", "y", "x"))
        if cube.ndim != 3:
            raise InputError(f"the {name} reflectance must be 3-D (band, y, x), got dims {cube.dims}")
        cubes.append(cube)
    if cubes[0].shape != cubes[1].shape:
        raise InputError(f"the before and after reflectance differ in shape: {cubes[0].shape} and {cubes[1].shape} "
                         "(band, y, x); give the corrected image of the same scene")
    return cubes[0], cubes[1]


def _band_coords(cube: xr.DataArray) -> dict[str, Any]:
    n_bands = cube.shape[0]
    band_dim = cube.dims[0]
    numbers = cube[band_dim].values if band_dim in cube.coords else np.arange(1, n_bands + 1)
    coords: dict[str, Any] = {"band": ("band", np.asarray(numbers))}
    if "wavelength" in cube.coords:
        coords["wavelength"] = ("band", np.asarray(cube["wavelength"].values, float), {"units": "nm"})
    return coords


def _layer(value, name: str, shape: tuple[int, ...]):
    if value is None:
        return None
    data = value.data if isinstance(value, xr.DataArray) else value
    if tuple(np.shape(data)) != shape:
        raise InputError(f"{name} has shape {tuple(np.shape(data))}, the reflectance's grid is {shape}")
    return data


def assess_view_angles(
    before, after, classes, vza, vaa, saa=None, *, by: Literal["sun", "track"] = "sun",
    heading: float | None = None, class_ids: Sequence[int] | None = None,
    class_names: Mapping[int, str] | None = None, bin_width: float = 2.0, min_vza: float = 0.0,
    flip_view_azimuth: bool = False, scheduler: str | None = None, num_workers: int | None = None,
) -> xr.Dataset:
    """Per class and band, before and after a correction: the slope of reflectance against the
    signed view zenith, the ratio of the two sides of nadir and the across-track profile.

    Parameters
    ----------
    before, after : xarray.DataArray or array (band, y, x)
        Reflectance [1] before and after the correction, on one grid (numpy or dask). Only pixels
        valid (finite) in every band of both enter, so both stages are measured on the same pixels.
    classes : xarray.DataArray or array (y, x)
        Class map: ids > 0; 0, NaN and the map's rioxarray nodata are no class.
    vza, vaa, saa : xarray.DataArray or array (y, x)
        View zenith, view azimuth and solar azimuth [deg] (``docs/conventions.md``); ``saa`` is
        needed for ``by="sun"``. Pixels with a view zenith outside [0°, 90°) are left out.
    by, heading :
        The sign convention (:func:`signed_view_zenith`).
    class_ids : sequence of int, optional
        Classes to assess (default: every class id in the map).
    class_names : mapping of int to str, optional
        Names for the report and the figures (default ``class ID``).
    bin_width : float, default 2
        Width of the bins of signed view zenith of the profiles [deg]; bins are centred on
        multiples of it shifted by half a width, so that nadir is a bin edge.
    min_vza : float, default 0
        The side ratio compares pixels with ``|signed vza| >= min_vza`` [deg] (and never 0).
    flip_view_azimuth : bool, default False
        ``vaa`` is stored as seen from the sensor: add 180°.
    scheduler, num_workers : optional
        dask scheduler and workers of the one compute (as for :func:`dask.compute`).

    Returns
    -------
    xarray.Dataset
        Dims ``stage`` (before, after), ``band``, ``class``, ``vza_bin``, ``side`` (negative,
        positive), with variables

        - ``pixels`` (class): valid pixels;
        - ``mean`` (stage, band, class): mean reflectance R̄ [1];
        - ``slope`` (stage, band, class): least-squares slope b of R against the signed view
          zenith θ [1/deg] (Notes);
        - ``relative_slope`` (stage, band, class): 1000 · b / R̄ [%/10 deg];
        - ``side_ratio`` (stage, band, class): mean R on the positive side over that on the negative
          side [-] (forward/backward with ``by="sun"``, right/left with ``by="track"``), 1 when
          the sides agree; ``side_pixels`` (class, side);
        - ``profile`` (stage, band, class, vza_bin): mean R per bin [1], NaN where empty;
          ``bin_pixels`` (class, vza_bin); coordinate ``vza_bin``: the bin centres [deg],
          ``vza_bin_edges`` (vza_bin, 2) its edges. Bins from the first to the last non-empty one.

        attrs ``sign_convention``, ``positive_side``, ``negative_side``, ``heading``, ``min_vza``.

    Notes
    -----
    The slope is the ordinary least-squares estimate
    b = Σ(θ − θ̄)(R − R̄) / Σ(θ − θ̄)², computed from the sums n, Σθ, Σθ², ΣR, ΣθR of one pass as
    b = (ΣθR/n − θ̄R̄) / (Σθ²/n − θ̄²); NaN when a class is seen at one signed zenith only. A
    correction that worked leaves b ≈ 0 and a side ratio ≈ 1 in every class and band.
    """
    before, after = _check_cubes(before, after)
    if by not in SIGN_CONVENTIONS:
        raise InputError(f"sign convention {by!r} is not one of {', '.join(SIGN_CONVENTIONS)}")
    if not (math.isfinite(bin_width) and 0 < bin_width <= 90):
        raise InputError(f"bin width {bin_width} deg must be in (0, 90]")
    if not (math.isfinite(min_vza) and 0 <= min_vza < 90):
        raise InputError(f"min_vza {min_vza} deg must be in [0, 90)")
    shape = before.shape[1:]
    layers = [_layer(value, name, shape) for name, value in
              (("the class map", classes), ("vza", vza), ("vaa", vaa), ("saa", saa))]
    if layers[3] is None and by == "sun":
        raise InputError("the signed view zenith by the sun needs the solar azimuth (saa)")
    ids = np.sort(np.asarray(class_ids if class_ids is not None else _present_ids(classes, _class_nodata(classes))))
    if ids.size == 0:
        raise InputError("the class map holds no class (no id > 0 outside its nodata)")
    half = math.ceil(90.0 / bin_width)
    edges = bin_width * np.arange(-half, half + 1, dtype=np.float64)
    options = dict(ids=ids, edges=edges, by=by, heading=heading, min_vza=float(min_vza),
                   flip_view_azimuth=flip_view_azimuth)
    compute = {key: value for key, value in (("scheduler", scheduler), ("num_workers", num_workers)) if value}
    sums = _scene_sums([before.data, after.data, *layers], options, compute)
    return _statistics(sums, ids, edges, before, class_names or {},
                       {"sign_convention": by, "heading": heading, "min_vza": float(min_vza)})


def _statistics(sums: _Sums, ids: np.ndarray, edges: np.ndarray, cube: xr.DataArray,
                names: Mapping[int, str], settings: dict) -> xr.Dataset:
    """The statistics of :func:`assess_view_angles` from the sums."""
    n = sums.n
    mean = _divide(sums.r, n)
    mean_s = _divide(sums.s, n)
    variance = _divide(sums.ss, n) - mean_s**2
    covariance = _divide(sums.sr, n) - mean_s * mean
    slope = _divide(covariance, np.where(variance > 1e-12 * np.maximum(_divide(sums.ss, n), 1.0), variance, 0.0))
    occupied = np.flatnonzero(sums.bin_n.sum(axis=0) > 0)
    keep = slice(occupied[0], occupied[-1] + 1) if occupied.size else slice(0, 0)
    bin_n = sums.bin_n[:, keep]
    lower, upper = edges[:-1][keep], edges[1:][keep]
    side_mean = _divide(sums.side_r, sums.side_n)
    data = {
        "pixels": (("class",), n.astype(np.int64), {"long_name": "valid pixels", "units": "1"}),
        "mean": (("stage", "band", "class"), mean, {"long_name": "mean reflectance", "units": "1"}),
        "slope": (("stage", "band", "class"), slope,
                  {"long_name": "least-squares slope of reflectance against signed view zenith", "units": "1/degree"}),
        "relative_slope": (("stage", "band", "class"), 1000.0 * _divide(slope, mean),
                           {"long_name": "slope relative to the class mean", "units": "%/10 degree"}),
        "side_ratio": (("stage", "band", "class"), _divide(side_mean[..., 1], side_mean[..., 0]),
                       {"long_name": "mean reflectance, positive over negative side of nadir", "units": "1"}),
        "side_pixels": (("class", "side"), sums.side_n.astype(np.int64), {"units": "1"}),
        "profile": (("stage", "band", "class", "vza_bin"), _divide(sums.bin_r[..., keep], bin_n),
                    {"long_name": "mean reflectance per bin of signed view zenith", "units": "1"}),
        "bin_pixels": (("class", "vza_bin"), bin_n.astype(np.int64), {"units": "1"}),
    }
    coords = {
        "stage": ("stage", list(STAGES)),
        **_band_coords(cube),
        "class": ("class", ids.astype(np.int64)),
        "class_name": ("class", [names.get(int(i), f"class {int(i)}") for i in ids]),
        "side": ("side", ["negative", "positive"]),
        "vza_bin": ("vza_bin", (lower + upper) / 2, {"long_name": "signed view zenith, bin centre", "units": "degree"}),
        "vza_bin_edges": (("vza_bin", "edge"), np.stack([lower, upper], axis=-1), {"units": "degree"}),
    }
    positive, negative = _SIGN_WORDS[settings["sign_convention"]]
    attrs = {**{k: v for k, v in settings.items() if v is not None}, "positive_side": positive,
             "negative_side": negative}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _json_numbers(values) -> Any:
    """A number or (nested) list with NaN and infinities as None (valid JSON)."""
    array = np.asarray(values, dtype=float)
    if array.ndim == 0:
        value = float(array)
        return value if math.isfinite(value) else None
    return [_json_numbers(item) for item in array]


def _band_list(dataset: xr.Dataset) -> list[dict[str, object]]:
    bands = []
    for index, number in enumerate(dataset["band"].values):
        entry: dict[str, object] = {"band": int(number)}
        if "wavelength" in dataset.coords:
            entry["wavelength_nm"] = float(dataset["wavelength"].values[index])
        bands.append(entry)
    return bands


def _stage_summary(values: xr.DataArray) -> dict[str, object]:
    """Median and maximum of |values| over every class and band, per stage."""
    summary = {}
    for stage in STAGES:
        magnitudes = np.abs(values.sel(stage=stage).values)
        magnitudes = magnitudes[np.isfinite(magnitudes)]
        summary[stage] = {"median": _json_numbers(np.median(magnitudes)) if magnitudes.size else None,
                          "max": _json_numbers(magnitudes.max()) if magnitudes.size else None}
    return summary


def view_angle_report(dataset: xr.Dataset) -> dict[str, object]:
    """The result of :func:`assess_view_angles` as a JSON-serialisable dict.

    Per class (id, name, pixels) and stage: per band lists of ``mean`` [1], ``slope`` [1/deg],
    ``relative_slope`` [%/10 deg] and ``side_ratio`` [-]; the profile (bin edges [deg], pixels,
    mean per band and bin). ``summary``: median and largest |relative slope| and |side ratio − 1|
    [%] over classes and bands, before and after.
    """
    classes = []
    for index, class_id in enumerate(dataset["class"].values):
        one = dataset.isel({"class": index})
        entry: dict[str, object] = {"id": int(class_id), "name": str(one["class_name"].values),
                                    "pixels": int(one["pixels"])}
        for stage in STAGES:
            values = one.sel(stage=stage)
            entry[stage] = {name: _json_numbers(values[name].values)
                            for name in ("mean", "slope", "relative_slope", "side_ratio")}
        entry["side_pixels"] = {"negative": int(one["side_pixels"].values[0]),
                                "positive": int(one["side_pixels"].values[1])}
        entry["profile"] = {
            "vza_bin_edges_deg": _json_numbers(one["vza_bin_edges"].values),
            "pixels": [int(v) for v in one["bin_pixels"].values],
            **{stage: _json_numbers(one["profile"].sel(stage=stage).values) for stage in STAGES},
        }
        classes.append(entry)
    return {
        "sign": {key: dataset.attrs[key] for key in ("sign_convention", "positive_side", "negative_side", "heading",
                                                      "min_vza") if key in dataset.attrs},
        "units": {"mean": "1", "slope": "1/degree", "relative_slope": "%/10 degree", "side_ratio": "1"},
        "bands": _band_list(dataset),
        "classes": classes,
        "summary": {"abs_relative_slope_percent_per_10deg": _stage_summary(dataset["relative_slope"]),
                    "abs_side_ratio_minus_1_percent": _stage_summary(100.0 * (dataset["side_ratio"] - 1.0))},
    }


# -------------------------------------------------------------------------------- overlap
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
    box = _overlap_box(before, other_before)
    this = list(dask.compute(*[line.rio.clip_box(*box) for line in (before, after)]))  # the overlap, read once
    other = [line.rio.clip_box(*box, crs=before.rio.crs).rio.reproject_match(this[0], resampling=method)
             for line in (other_before, other_after)]
    cubes = [np.asarray(line.values, dtype=np.float64) for line in (*this, *other)]
    valid = np.logical_and.reduce([np.isfinite(cube).all(axis=0) for cube in cubes])
    differences = [cubes[2] - cubes[0], cubes[3] - cubes[1]]
    statistics = [_difference_statistics(d[:, valid], (c[:, valid] + o[:, valid]) / 2)
                  for d, c, o in ((differences[0], cubes[0], cubes[2]), (differences[1], cubes[1], cubes[3]))]
    band_means = [np.where(valid, d.mean(axis=0), np.nan) for d in differences]
    reach = max((np.nanpercentile(np.abs(m), 99.5) for m in band_means if np.isfinite(m).any()), default=1.0)
    reach = reach if reach > 0 else 1e-6  # identical lines: a narrow histogram around 0
    edges = np.linspace(-reach, reach, histogram_bins + 1)
    histograms = [np.histogram(np.clip(m[valid], edges[0], edges[-1]), edges)[0] for m in band_means]
    maps = [_coarse_map(m, map_size) for m in band_means]
    stat = {name: (("stage", "band"), np.stack([s[name] for s in statistics]),
                   {"units": "%" if name == "relative_rmse" else "1"}) for name in statistics[0]}
    dataset = xr.Dataset(
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
    return dataset


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


# ------------------------------------------------------------------------ leave one line out
class Line(NamedTuple):
    """One flight line in memory: reflectance (band, y, x) [1], class map (y, x) and the angles
    ``sza``, ``saa``, ``vza``, ``vaa`` (y, x) [deg] on its grid (georeferenced for overlaps)."""

    name: str
    reflectance: xr.DataArray
    classes: xr.DataArray
    angles: Mapping[str, xr.DataArray]


@dataclass
class HeldOutLine:
    """One line of :func:`leave_one_line_out`: assessed after a correction with parameters fitted
    on the other lines.

    Attributes
    ----------
    name : str
    table : ParameterTable
        The parameters fitted without this line.
    view : xarray.Dataset
        :func:`assess_view_angles` of the line before and after.
    overlaps : dict of str to xarray.Dataset
        :func:`assess_overlap` against each overlapping other line (both corrected with ``table``).
    fit_report : list of dict
        The fit's per-class report (:meth:`brdfcorr.fit.ClassFitResult.report`).
    """

    name: str
    table: Any
    view: xr.Dataset
    overlaps: dict[str, xr.Dataset] = field(default_factory=dict)
    fit_report: list = field(default_factory=list)


def _overlaps(a: xr.DataArray, b: xr.DataArray) -> bool:
    try:
        _overlap_box(a, b)
    except InputError:
        return False
    return True


def leave_one_line_out(
    lines: Sequence[Line], model: str = "torrance_sparrow", *, class_models: Mapping[int, str] | None = None,
    names: Mapping[int, str] | None = None, fixed: Mapping[str, float] | None = None,
    reference: Mapping[str, object] | None = None, limits: tuple[float, float] | None = DEFAULT_LIMITS,
    max_samples: int = 50_000, seed: int = 0, by: Literal["sun", "track"] = "sun",
    heading: float | None = None, bin_width: float = 2.0, overlap: bool = True,
    flip_view_azimuth: bool = False,
) -> list[HeldOutLine]:
    """Fit on N − 1 lines, correct the held-out one, assess it: for each of N lines.

    Parameters
    ----------
    lines : sequence of Line
        At least 2 lines (angles by name ``sza``, ``saa``, ``vza``, ``vaa`` [deg]).
    model, class_models, names, fixed, max_samples, seed :
        The imagery fit, as for :func:`brdfcorr.fit.fit_classes` (its default guard rails; a
        class that fails them is left uncorrected).
    reference : mapping, optional
        Reference geometry of the correction (:func:`brdfcorr.normalize`; default: the scene-mean
        sun zenith, nadir view).
    limits : (float, float) or None
        Limits of the correction factor.
    by, heading, bin_width :
        As for :func:`assess_view_angles`.
    overlap : bool, default True
        Also compare the held-out line with every other line it overlaps (both corrected with the
        parameters fitted without it), :func:`assess_overlap`.
    flip_view_azimuth : bool, default False
        ``vaa`` is stored as seen from the sensor.

    Returns
    -------
    list of HeldOutLine
        One per line, in order.
    """
    from brdfcorr.correct import normalize
    from brdfcorr.fit import fit_classes

    if len(lines) < 2:
        raise InputError(f"leave-one-line-out needs at least 2 lines, got {len(lines)}")
    reference = dict(reference) if reference is not None else {"sza": "mean", "vza": 0.0}
    results = []
    for held, line in enumerate(lines):
        training = [other for index, other in enumerate(lines) if index != held]
        fitted = fit_classes([t.reflectance for t in training], [t.classes for t in training],
                             [xr.Dataset(dict(t.angles)) for t in training], model, class_models=class_models,
                             names=names, fixed=fixed, max_samples=max_samples, seed=seed)

        def corrected(target: Line, table=fitted.table) -> xr.DataArray:
            angles = target.angles
            return normalize(target.reflectance, target.classes, angles["sza"], angles["saa"], angles["vza"],
                             angles["vaa"], table, reference, limits=limits,
                             flip_view_azimuth=flip_view_azimuth).reflectance

        after = corrected(line)
        view = assess_view_angles(line.reflectance, after, line.classes, line.angles["vza"], line.angles["vaa"],
                                  line.angles["saa"], by=by, heading=heading, class_names=names,
                                  bin_width=bin_width, flip_view_azimuth=flip_view_azimuth)
        overlaps = {}
        if overlap:
            for other in training:
                if _overlaps(line.reflectance, other.reflectance):
                    overlaps[other.name] = assess_overlap(line.reflectance, after, other.reflectance,
                                                          corrected(other))
        results.append(HeldOutLine(line.name, fitted.table, view, overlaps, fitted.report()))
    return results


def leave_one_line_out_report(results: Sequence[HeldOutLine]) -> dict[str, object]:
    """:func:`leave_one_line_out` as a JSON-serialisable dict: per held-out line its view-angle
    report, its overlap reports by other line, and the fit without it."""
    return {
        "kind": "leave-one-line-out",
        "lines": [{"held_out": result.name, "view_angles": view_angle_report(result.view),
                   "overlaps": {name: overlap_report(data) for name, data in result.overlaps.items()},
                   "fit": result.fit_report} for result in results],
    }
