"""The view-angle signal left in a scene, per class and band, before and after a correction.

:func:`assess_view_angles` measures the least-squares slope of reflectance against the *signed*
view zenith (:func:`~brdfcorr.analysis.signed_view.signed_view_zenith`), absolute [1/deg] and
relative [%/10 deg]; the ratio of the mean reflectance on the positive side of nadir to that on
the negative side (forward/backward scattering, or right/left of the flight direction); and the
across-track profile, the mean reflectance in bins of signed view zenith. One chunk-wise pass over the before
and after cubes (dask: per-block sums, :class:`_Sums`, added in a tree, one compute).
:func:`view_angle_report` turns the result into a plain dict (NaN as ``None``, valid JSON).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import dask
import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr

from brdfcorr.analysis._assess_common import STAGES, _band_coords, _band_list, _divide, _json_numbers
from brdfcorr.analysis.signed_view import _SIGN_WORDS, SIGN_CONVENTIONS, check_signing
from brdfcorr.analysis.view_angle_sums import _scene_sums, _SumOptions, _Sums
from brdfcorr.analysis.view_stripes import (
    CLUSTER_LAYER,
    STRIPE_LIMIT,
    class_stripe_ratios,
    stripe_ratio,
    stripe_warning,
)
from brdfcorr.correction.checks import angle_statistics, as_dataarray, check_grid
from brdfcorr.defaults import MAX_BLOCK_SIZE, MIN_BIN_WIDTH
from brdfcorr.errors import BrdfcorrWarning, InputError
from brdfcorr.io.angles import check_angle_values
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.reflectance import declared_nodata, reflectance_factors, unpacked
from brdfcorr.io.writer import local_scheduler

__all__ = ["GROWTH_LIMIT", "STRIPE_LIMIT", "ViewAngleOptions", "assess_view_angles", "error_growth_warning",
           "narrow_range_warning", "stripe_warning", "view_zenith_ranges", "view_angle_report"]

#: The slopes' 1-sigma from blocks of twice the block size over the one reported, above which
#: :func:`assess_view_angles` warns that the errors are correlated beyond its clusters. Under
#: independent errors the ratio scatters about 1 (``benchmarks/bench_assess_coverage.py`` counts
#: how often it passes 1.25 by chance and how often correlated errors pass it).
GROWTH_LIMIT = 1.25

#: The signed view zenith range [deg] below which :func:`assess_view_angles` warns that a class's
#: slope, reported per 10 deg, is extrapolated beyond the view angles it was measured over: the
#: unit of the slope itself.
NARROW_RANGE = 10.0


#: The largest profile sums (2 stages x bands x classes x bins of signed view zenith, float64) a
#: chunk's partial sums may hold [bytes]: a bin width of 0.01 deg (18 000 bins) with 425 bands and
#: 20 classes would be 2.4 GB per chunk.
MAX_PROFILE_BYTES = 64 * 2**20


def _check_profile_size(n_bands: int, n_classes: int, bin_width: float) -> None:
    """Refuse a bin width [deg] whose profiles would exceed :data:`MAX_PROFILE_BYTES` per chunk,
    naming the narrowest that fits."""
    size = 2 * n_bands * n_classes * math.ceil(90.0 / bin_width) * 2 * 8
    if size > MAX_PROFILE_BYTES:
        narrowest = bin_width * size / MAX_PROFILE_BYTES
        raise InputError(f"bin width {bin_width:g} deg: the profiles of {n_bands} bands and {n_classes} classes "
                         f"would take {size / 2**20:.0f} MiB in every chunk's sums (at most "
                         f"{MAX_PROFILE_BYTES / 2**20:.0f}); give a bin width of at least "
                         f"{math.ceil(narrowest * 100) / 100:g} deg")


def _check_options(options: ViewAngleOptions) -> None:
    """Raise :class:`InputError` for an unknown sign convention, a bin width [deg] outside
    [:data:`MIN_BIN_WIDTH`, 90], a smallest view zenith [deg] outside [0, 90) or a block size that is
    not a whole number of pixels from 1 to :data:`MAX_BLOCK_SIZE`."""
    by, bin_width, min_vza = options.by, options.bin_width, options.min_vza
    if by not in SIGN_CONVENTIONS:
        raise InputError(f"sign convention {by!r} is not one of {', '.join(SIGN_CONVENTIONS)}")
    if not (math.isfinite(bin_width) and MIN_BIN_WIDTH <= bin_width <= 90):
        raise InputError(f"bin width {bin_width} deg must be in [{MIN_BIN_WIDTH}, 90]")
    if not (math.isfinite(min_vza) and 0 <= min_vza < 90):
        raise InputError(f"min_vza {min_vza} deg must be in [0, 90)")
    if not (isinstance(options.block_size, int) and 1 <= options.block_size <= MAX_BLOCK_SIZE):
        raise InputError(f"block size {options.block_size} must be a whole number of pixels from 1 to {MAX_BLOCK_SIZE}")


def _present_ids(classes, nodata, scheduler=None) -> np.ndarray:
    """The positive class ids of a class map (its nodata value excepted; a dask map computed on
    ``scheduler``)."""
    data = classes.data if isinstance(classes, xr.DataArray) else classes
    if isinstance(data, da.Array):  # each chunk's ids, then theirs (dask.array.unique imports dask.distributed)
        chunks = [dask.delayed(np.unique)(chunk) for chunk in data.to_delayed().ravel()]
        values = np.unique(np.concatenate(dask.compute(*chunks, scheduler=local_scheduler(scheduler))))
    else:
        values = np.unique(np.asarray(data))
    values = values[np.isfinite(values) & (values > 0)]
    return values[values != nodata] if nodata is not None else values


def _class_nodata(classes):
    if isinstance(classes, xr.DataArray):
        nodata = declared_nodata(classes)
        return None if nodata is None or (isinstance(nodata, float) and math.isnan(nodata)) else nodata
    return None


def _check_cubes(before, after) -> tuple[xr.DataArray, xr.DataArray]:
    """Both cubes as reflectance factors (:func:`~brdfcorr.io.reflectance.reflectance_factors`:
    counts with their scale and offset, as :func:`~brdfcorr.correction.normalize` takes them; int16
    counts were assessed as they were, the slopes 7 times too small), ``after`` on ``before``'s
    grid (its rows sorted otherwise paired other pixels)."""
    cubes = []
    for name, cube in (("before", before), ("after", after)):
        cube = as_dataarray(cube, f"the {name} reflectance", ("band", "y", "x"))
        if cube.ndim != 3:
            raise InputError(f"the {name} reflectance must be 3-D (band, y, x), got dims {cube.dims}")
        cubes.append(reflectance_factors(cube))
    if cubes[0].shape != cubes[1].shape:
        raise InputError(f"the before and after reflectance differ in shape: {cubes[0].shape} and {cubes[1].shape} "
                         "(band, y, x); give the corrected image of the same scene")
    check_same_grid({"the before reflectance": cubes[0], "the after reflectance": cubes[1]})
    return cubes[0], cubes[1]


def _checked_layers(before: xr.DataArray, named: Mapping[str, object]) -> list:
    """The class map, angle and cluster layers ``named`` (None: not given) as (y, x) arrays on
    ``before``'s grid, as :func:`~brdfcorr.correction.normalize` takes them
    (:func:`~brdfcorr.correction.checks.check_grid`: transposed by name, rows running the other
    way refused; they were paired by position), the angles unpacked (int16 hundredths of a degree
    with a ``scale_factor``) and, held in memory, refused where they look like radians."""
    layers = {name: None if value is None else check_grid(before, name, as_dataarray(value, name, before.dims[1:]))
              for name, value in named.items()}
    angles = {name: unpacked(layers[name], name) for name in ("vza", "vaa", "saa") if layers[name] is not None}
    statistics = {name: angle_statistics(np.asarray(layer.data)) for name, layer in angles.items()
                  if not isinstance(layer.data, da.Array)}
    check_angle_values({name: found[0] for name, found in statistics.items()},
                       {name: found[1] for name, found in statistics.items()}, lambda name: name, whole=False)
    return [None if layer is None else layer.data for layer in {**layers, **angles}.values()]


@dataclass(frozen=True)
class ViewAngleOptions:
    """How the view-angle signal is measured (:func:`assess_view_angles`); shared by
    :func:`brdfcorr.analysis.holdout.leave_one_line_out`, the files' assessments
    (:mod:`brdfcorr.tasks.assess`) and the chains' assess step.

    Attributes
    ----------
    by : {"sun", "track"}, default "sun"
        The sign convention of the view zenith (:func:`~brdfcorr.analysis.signed_view.signed_view_zenith`).
    heading : float, optional
        Flight direction [deg], clockwise from north; needed for ``by="track"``.
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
    block_size : int, default 32
        Side [pixels] of the square blocks over which the slope's standard error is
        cluster-robust: pixels of one block may share their errors (a field, a roof), pixels of
        different blocks are taken as independent. Errors shared by pixels far apart (a
        composite's acquisition day, whose pixels lie in patches spread over the scene; a flight
        line; a detector's strip) need a cluster layer (:func:`assess_view_angles`).
    """

    by: Literal["sun", "track"] = "sun"
    heading: float | None = None
    class_ids: Sequence[int] | None = None
    class_names: Mapping[int, str] | None = None
    bin_width: float = 2.0
    min_vza: float = 0.0
    flip_view_azimuth: bool = False
    block_size: int = 32


def assess_view_angles(
    before, after, classes, vza, vaa, saa=None, *, clusters=None, options: ViewAngleOptions = ViewAngleOptions(),
    scheduler: str | None = None, num_workers: int | None = None,
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
    clusters : xarray.DataArray or array (y, x), optional
        Integer ids of the units whose pixels share their errors (a composite's day-of-year band, a
        flight-line or detector id): the slopes' 1-sigma is then cluster-robust over these (per
        class, the pixels of one id form one cluster, wherever they lie) instead of square blocks.
        Pixels with a non-finite id or the layer's rioxarray nodata are left out.
    options : ViewAngleOptions
        The sign convention and flight direction, the classes and their names, the profiles' bin
        width and the side ratio's smallest view zenith [deg], the view azimuth's convention.
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
        - ``relative_slope`` (stage, band, class): 1000 · b / |R̄| [%/10 deg] (a negative mean, dark
          water after an offset, keeps the slope's sign; NaN where R̄ = 0);
        - ``relative_slope_error`` (stage, band, class): its 1-sigma [%/10 deg], cluster-robust
          (:func:`_cluster_error`) over the ids of ``clusters`` if given, else over square blocks
          of ``options.block_size`` pixels; ``blocks`` (class): the clusters holding the class's
          pixels (ids or blocks);
        - ``relative_slope_error_blocks`` (stage, band, class, block_size): the 1-sigma over
          square blocks of ``options.block_size`` and of twice that (coordinate ``block_size``
          [pixels]); ``error_growth`` (stage, band, class): the 1-sigma over the larger blocks
          divided by ``relative_slope_error``. Well above 1 (more than :data:`GROWTH_LIMIT`;
          :func:`error_growth_warning`), the errors are correlated beyond the clusters and the
          1-sigma is too small;
        - ``stripe_ratio`` (stage, band, class): the 1-sigma with the bins of signed view zenith
          (over the whole scene) as clusters, the bins' smooth trend taken out, over
          ``relative_slope_error`` (:func:`brdfcorr.analysis.view_stripes.stripe_ratio`). Well
          above 1 (more than :data:`STRIPE_LIMIT`; :func:`stripe_warning`), errors are shared
          along the track at one view angle (a detector's stripes) and the 1-sigma is too small;
        - ``side_ratio`` (stage, band, class): mean R on the positive side over that on the negative
          side [-] (forward/backward with ``by="sun"``, right/left with ``by="track"``), 1 when
          the sides agree; ``side_pixels`` (class, side);
        - ``profile`` (stage, band, class, vza_bin): mean R per bin [1], NaN where empty;
          ``bin_pixels`` (class, vza_bin); coordinate ``vza_bin``: the bin centres [deg],
          ``vza_bin_edges`` (vza_bin, 2) its edges. Bins from the first to the last non-empty one.

        attrs ``sign_convention``, ``positive_side``, ``negative_side``, ``heading``, ``min_vza``,
        ``error_clusters`` (what the 1-sigma is cluster-robust over).

    Warns
    -----
    BrdfcorrWarning
        One line (:func:`error_growth_warning`) where a class's 1-sigma grows with the block; one
        line (:func:`stripe_warning`) where it is too small for errors shared at one view angle
        along the track; one line (:func:`narrow_range_warning`) where a class is seen over less
        than :data:`NARROW_RANGE` of signed view zenith.

    Notes
    -----
    The slope is the ordinary least-squares estimate
    b = Σ(θ − θ̄)(R − R̄) / Σ(θ − θ̄)², computed from the sums n, Σθ, Σθ², ΣR, ΣθR of one pass as
    b = (ΣθR/n − θ̄R̄) / (Σθ²/n − θ̄²); NaN when a class is seen at one signed zenith only. A
    correction that worked leaves b ≈ 0 and a side ratio ≈ 1 in every class and band.
    """
    before, after = _check_cubes(before, after)
    _check_options(options)
    by, bin_width, min_vza = options.by, options.bin_width, options.min_vza
    check_signing(by, vaa, saa)
    layers = _checked_layers(before, {"the class map": classes, "vza": vza, "vaa": vaa, "saa": saa,
                                      "the cluster layer": clusters})
    if layers[3] is None and by == "sun":
        raise InputError("the signed view zenith by the sun needs the solar azimuth (saa)")
    class_ids = options.class_ids
    scheduler = local_scheduler(scheduler)  # a local pass without dask.distributed (io.writer)
    ids = np.sort(np.asarray(class_ids if class_ids is not None else
                             _present_ids(classes, _class_nodata(classes), scheduler)))
    if ids.size == 0:
        raise InputError("the class map holds no class (no id > 0 outside its nodata)")
    fractional = ids[ids != np.round(ids)]
    if fractional.size:  # each would be assessed apart, and reported under its integer part
        raise InputError(f"class ids are whole numbers; {'class_ids' if class_ids is not None else 'the class map'} "
                         f"holds {', '.join(f'{value:g}' for value in fractional[:3])}")
    _check_profile_size(before.shape[0], ids.size, bin_width)
    half = math.ceil(90.0 / bin_width)
    edges = bin_width * np.arange(-half, half + 1, dtype=np.float64)
    summing = _SumOptions(ids=ids, edges=edges, by=by, heading=options.heading, min_vza=float(min_vza),
                          flip_view_azimuth=options.flip_view_azimuth, block_size=options.block_size,
                          cluster_nodata=_class_nodata(clusters))
    compute = {key: value for key, value in (("scheduler", scheduler), ("num_workers", num_workers)) if value}
    sums = _scene_sums([before.data, after.data, *layers], summing, compute)
    clustered = CLUSTER_LAYER if clusters is not None else f"square blocks of {options.block_size} pixels"
    result = _statistics(sums, ids, edges, before, options.class_names or {},
                         {"sign_convention": by, "heading": options.heading, "min_vza": float(min_vza),
                          "error_clusters": clustered}, options.block_size, clusters is not None)
    for message in (error_growth_warning(result), stripe_warning(result), narrow_range_warning(result),
                    few_clusters_warning(result)):
        if message is not None:
            warnings.warn(message, BrdfcorrWarning, stacklevel=2)
    return result


def _statistics(sums: _Sums, ids: np.ndarray, edges: np.ndarray, cube: xr.DataArray,
                names: Mapping[int, str], settings: dict, block_size: int, clustered: bool) -> xr.Dataset:
    """The statistics of :func:`assess_view_angles` from the sums."""
    n = sums.n
    mean = _divide(sums.r, n)
    mean_s = _divide(sums.s, n)
    variance = _divide(sums.ss, n) - mean_s**2
    covariance = _divide(sums.sr, n) - mean_s * mean
    slope = _divide(covariance, np.where(variance > 1e-12 * np.maximum(_divide(sums.ss, n), 1.0), variance, 0.0))
    slope_error, block_errors, groups = _slope_errors(sums, len(ids), (slope, n * variance), clustered)
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
        "relative_slope": (("stage", "band", "class"), 1000.0 * _divide(slope, np.abs(mean)),
                           {"long_name": "slope relative to the class mean", "units": "%/10 degree"}),
        "relative_slope_error": (("stage", "band", "class"), 1000.0 * _divide(slope_error, np.abs(mean)),
                                 {"long_name": "1-sigma of the relative slope, cluster-robust over spatial blocks",
                                  "units": "%/10 degree"}),
        "relative_slope_error_blocks": (("stage", "band", "class", "block_size"),
                                        1000.0 * _divide(block_errors, np.abs(mean)[..., None]),
                                        {"long_name": "1-sigma of the relative slope, cluster-robust over square "
                                                      "blocks of two sizes", "units": "%/10 degree"}),
        "error_growth": (("stage", "band", "class"), _divide(block_errors[..., 1], slope_error),
                         {"long_name": "1-sigma over blocks of twice the size over the 1-sigma reported",
                          "units": "1"}),
        "stripe_ratio": (("stage", "band", "class"),
                         stripe_ratio(sums.bin_n, sums.bin_s, sums.bin_r, (slope, mean, mean_s), n * variance,
                                      slope_error),
                         {"long_name": "1-sigma over bins of view zenith over the 1-sigma reported", "units": "1"}),
        "blocks": (("class",), groups.astype(np.int64), {"long_name": "clusters (ids or blocks) with pixels of the "
                                                                      "class", "units": "1"}),
        "side_ratio": (("stage", "band", "class"), _divide(side_mean[..., 1], side_mean[..., 0]),
                       {"long_name": "mean reflectance, positive over negative side of nadir", "units": "1"}),
        "side_pixels": (("class", "side"), sums.side_n.astype(np.int64), {"units": "1"}),
        "profile": (("stage", "band", "class", "vza_bin"), _divide(sums.bin_r[..., keep], bin_n),
                    {"long_name": "mean reflectance per bin of signed view zenith", "units": "1"}),
        "bin_pixels": (("class", "vza_bin"), bin_n.astype(np.int64), {"units": "1"}),
        "vza_width": (("class",), np.sqrt(12.0 * np.maximum(variance, 0.0)),
                      {"long_name": "spread of the signed view zenith: sqrt(12) x its standard deviation, "
                                    "the width of a uniform distribution with that spread", "units": "degree"}),
    }
    positive, negative = _SIGN_WORDS[settings["sign_convention"]]
    attrs = {**{k: v for k, v in settings.items() if v is not None}, "positive_side": positive,
             "negative_side": negative}
    return xr.Dataset(data, coords=_coords(cube, ids, names, block_size, lower, upper), attrs=attrs)


def _slope_errors(sums: _Sums, n_classes: int, terms: tuple, clustered: bool) -> tuple[np.ndarray, ...]:
    """The slopes' 1-sigma [1/deg] (:func:`_cluster_error`; ``terms``: slope, Sxx): cluster-robust
    over the cluster ids where ``clustered``, else over the square blocks; the 1-sigma over blocks
    of both sizes (..., 2); the clusters (ids or blocks) per class."""
    block_errors = np.stack([_cluster_error(sums.squares.moments, sums.squares.blocks, *terms),
                             _cluster_error(sums.squares2.moments, sums.squares2.blocks, *terms)], axis=-1)
    if not clustered:
        return block_errors[..., 0], block_errors, sums.squares.blocks
    groups, moments = sums.clusters.moments(n_classes)
    return _cluster_error(moments, groups, *terms), block_errors, groups


def _coords(cube: xr.DataArray, ids: np.ndarray, names: Mapping[int, str], block_size: int, lower: np.ndarray,
            upper: np.ndarray) -> dict:
    """The coordinates of the statistics: stage, band, class (id, name), side of nadir, block size
    [pixel] and the bins of signed view zenith (``lower`` to ``upper`` [deg])."""
    return {
        "stage": ("stage", list(STAGES)),
        **_band_coords(cube),
        "class": ("class", ids.astype(np.int64)),
        "class_name": ("class", [names.get(int(i), f"class {int(i)}") for i in ids]),
        "side": ("side", ["negative", "positive"]),
        "block_size": ("block_size", [block_size, 2 * block_size], {"units": "pixel"}),
        "vza_bin": ("vza_bin", (lower + upper) / 2, {"long_name": "signed view zenith, bin centre", "units": "degree"}),
        "vza_bin_edges": (("vza_bin", "edge"), np.stack([lower, upper], axis=-1), {"units": "degree"}),
    }


def _cluster_error(moments: np.ndarray, blocks: np.ndarray, slope, sxx) -> np.ndarray:
    """1-sigma of the least-squares slope [1/deg], cluster-robust over the spatial blocks (CR1,
    Liang and Zeger 1986; Cameron and Miller 2015, J. Hum. Resour. 50, 317-372, eq. 11):
    Var b = G/(G-1) Σ_g u_g² / Sxx², with u_g = Σ_{i in g} (θ_i − θ̄) e_i and the residuals
    e = R − a − bθ = (R − R̄) − b(θ − θ̄). u_g is linear in the block's sums v_g = (n, Σθ', Σθ'²,
    ΣR', Σθ'R') of θ' = θ − θ̄ and R' = R − R̄ (about the class means: :mod:`.view_angle_sums`):
    u_g = c·v_g with c = (0, 0, −b, 0, 1), so Σ_g u_g² = cᵀ (Σ_g v_g v_gᵀ) c. NaN with fewer than
    2 blocks. ``moments``: (2, B, K, 5, 5), Σ_g v_g v_gᵀ per class; ``blocks``: (K,) G."""
    scores = np.maximum(slope**2 * moments[..., 2, 2] - 2 * slope * moments[..., 2, 4] + moments[..., 4, 4], 0.0)
    factor = _divide(blocks, np.where(blocks > 1, blocks - 1, 0.0))
    return _divide(np.sqrt(factor * scores), sxx)


def _class_growth(dataset: xr.Dataset) -> np.ndarray:
    """Per class the median over bands of ``error_growth`` after the correction (the slopes the
    report tests against 0; NaN where no band has one)."""
    growth = dataset["error_growth"].sel(stage="after").values
    finite = np.isfinite(growth)
    return np.array([np.median(column[ok]) if ok.any() else np.nan for column, ok in zip(growth.T, finite.T)])


def error_growth_warning(dataset: xr.Dataset, limit: float = GROWTH_LIMIT) -> str | None:
    """One line where the slopes' 1-sigma of some class (median over its bands, after the
    correction) grows by more than ``limit`` from the reported clusters to blocks of twice the
    block size (:func:`assess_view_angles`, ``error_growth``); None otherwise.

    Errors correlated over more than one block (a composite's acquisition days, stripes along the
    view angle) make the cluster-robust 1-sigma too small, and more so the smaller the blocks:
    its growth with the block size shows it."""
    growth = _class_growth(dataset)
    if not np.isfinite(growth).any() or np.nanmax(growth) <= limit:
        return None
    worst = int(np.nanargmax(growth))
    size = int(dataset["block_size"].values[1])
    return (f"the slopes' 1-sigma grows {growth[worst]:.1f}x from {dataset.attrs['error_clusters']} to square "
            f"blocks of {size} pixels ({dataset['class_name'].values[worst]}; more than {limit:g}x): the errors are "
            "correlated beyond them and the 1-sigma is too small; " + (
                "the cluster layer's units are smaller than those that share errors: give coarser ones (several "
                "days, a whole flight line) or, without --clusters, a larger --block-size"
                if dataset.attrs["error_clusters"] == CLUSTER_LAYER else
                "give a cluster layer of the units that share errors (--clusters: a composite's day-of-year band, "
                "a flight-line id) or a larger --block-size"))


def view_zenith_ranges(dataset: xr.Dataset) -> np.ndarray:
    """Per class, the signed view zenith range [deg] its pixels cover: from the lower edge of its
    first non-empty bin to the upper edge of its last (:func:`assess_view_angles`); NaN without pixels."""
    edges = dataset["vza_bin_edges"].values
    ranges = np.full(dataset.sizes["class"], np.nan)
    for index, pixels in enumerate(dataset["bin_pixels"].values):
        seen = np.flatnonzero(pixels > 0)
        if seen.size:
            ranges[index] = edges[seen[-1], 1] - edges[seen[0], 0]
    return ranges


def narrow_range_warning(dataset: xr.Dataset, limit: float = NARROW_RANGE) -> str | None:
    """One line naming the classes seen over less than ``limit`` [deg] of signed view zenith (the
    width of a uniform spread with their pixels' standard deviation, ``vza_width``: from the
    pixels, not the bins, which are ``bin_width`` wide), whose slopes per 10 deg are extrapolated
    beyond the angles measured (their 1-sigma is large and their value says little); None otherwise."""
    widths = dataset["vza_width"].values
    narrow = np.flatnonzero((dataset["pixels"].values > 0) & (widths < limit))
    if narrow.size == 0:
        return None
    names = ", ".join(f"{dataset['class_name'].values[index]} ({widths[index]:.3g} deg)" for index in narrow)
    return (f"seen over less than {limit:g} deg of view zenith: {names}; their slopes per 10 deg extrapolate "
            "beyond the view angles measured: read them with their 1-sigma, or assess a wider swath")


def few_clusters_warning(dataset: xr.Dataset) -> str | None:
    """One line naming the classes whose pixels lie in a single cluster (an id of the cluster
    layer, or a square block): their slopes have no cluster-robust 1-sigma (NaN in the report);
    None otherwise."""
    alone = np.flatnonzero((dataset["pixels"].values > 0) & (dataset["blocks"].values < 2))
    if alone.size == 0:
        return None
    names = ", ".join(str(dataset["class_name"].values[index]) for index in alone)
    return (f"no 1-sigma for the slopes of {names}: the pixels of each lie in a single one of "
            f"{dataset.attrs.get('error_clusters', 'the clusters')}; give a cluster layer with more ids, or smaller "
            "blocks (--block-size)")


def _stage_summary(values: xr.DataArray) -> dict[str, object]:
    """Median and maximum of |values| over every class and band, per stage."""
    summary = {}
    for stage in STAGES:
        magnitudes = np.abs(values.sel(stage=stage).values)
        magnitudes = magnitudes[np.isfinite(magnitudes)]
        summary[stage] = {"median": _json_numbers(np.median(magnitudes)) if magnitudes.size else None,
                          "max": _json_numbers(magnitudes.max()) if magnitudes.size else None}
    return summary


def _within_two_sigma(dataset: xr.Dataset) -> dict[str, int]:
    """How many slopes of ``dataset`` (all its bands and classes) lie within 2 sigma of 0, per
    stage, of how many have a sigma."""
    measured = np.isfinite(dataset["relative_slope"]) & np.isfinite(dataset["relative_slope_error"])
    inside = measured & (np.abs(dataset["relative_slope"]) <= 2.0 * dataset["relative_slope_error"])
    return {**{stage: int(inside.sel(stage=stage).sum()) for stage in STAGES},
            "of": int(measured.sel(stage="after").sum())}


def view_angle_report(dataset: xr.Dataset) -> dict[str, object]:
    """The result of :func:`assess_view_angles` as a JSON-serialisable dict.

    Per class: id, name, pixels, blocks (the clusters of the 1-sigma), ``view_zenith_range_deg``
    (:func:`view_zenith_ranges`), ``error_growth`` (the
    median over bands of the 1-sigma's growth to blocks of twice the size, after the correction),
    ``bands_within_2_sigma`` (how many of its bands' slopes
    lie within 2 sigma of 0: ``before``, ``after``, ``of``) and per stage the per band lists of
    ``mean`` [1], ``slope`` [1/deg], ``relative_slope``, ``relative_slope_error`` and
    ``relative_slope_error_double_block`` (over blocks of twice the block size) [%/10 deg] and
    ``side_ratio`` [-]; the profile (bin edges [deg], pixels, mean per band and bin).
    ``summary``: median and largest |relative slope| and |side ratio − 1| [%] over classes and
    bands, before and after, and how many class-band slopes lie within 2 sigma of 0
    (``slopes_within_2_sigma``: ``before``, ``after``, ``of``). ``errors``: what the 1-sigma is
    cluster-robust over, the two block sizes [pixels], the warnings of
    :func:`error_growth_warning` (``warning``) and :func:`stripe_warning` (``stripes``), or None.
    Per class also ``stripe_ratio``: the median over bands, after the correction, of the 1-sigma
    over bins of view zenith over the one reported (:func:`stripe_warning`).
    """
    growth, ranges, stripes = _class_growth(dataset), view_zenith_ranges(dataset), class_stripe_ratios(dataset)
    classes = []
    for index, class_id in enumerate(dataset["class"].values):
        one = dataset.isel({"class": index})
        entry: dict[str, object] = {"id": int(class_id), "name": str(one["class_name"].values),
                                    "pixels": int(one["pixels"]), "blocks": int(one["blocks"]),
                                    "error_growth": _json_numbers(growth[index]),
                                    "stripe_ratio": _json_numbers(stripes[index]),
                                    "view_zenith_range_deg": _json_numbers(ranges[index])}
        for stage in STAGES:
            values = one.sel(stage=stage)
            entry[stage] = {name: _json_numbers(values[name].values)
                            for name in ("mean", "slope", "relative_slope", "relative_slope_error", "side_ratio")}
            entry[stage]["relative_slope_error_double_block"] = _json_numbers(
                values["relative_slope_error_blocks"].isel(block_size=1).values)
        entry["bands_within_2_sigma"] = _within_two_sigma(one)
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
        "units": {"mean": "1", "slope": "1/degree", "relative_slope": "%/10 degree",
                  "relative_slope_error": "%/10 degree", "relative_slope_error_double_block": "%/10 degree",
                  "side_ratio": "1"},
        "errors": {"clusters": dataset.attrs.get("error_clusters"),
                   "block_sizes": [int(size) for size in dataset["block_size"].values],
                   "warning": error_growth_warning(dataset), "stripes": stripe_warning(dataset),
                   "narrow": narrow_range_warning(dataset)},
        "bands": _band_list(dataset),
        "classes": classes,
        "summary": {"abs_relative_slope_percent_per_10deg": _stage_summary(dataset["relative_slope"]),
                    "slopes_within_2_sigma": _within_two_sigma(dataset),
                    "abs_side_ratio_minus_1_percent": _stage_summary(100.0 * (dataset["side_ratio"] - 1.0))},
    }
