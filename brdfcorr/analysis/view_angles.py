"""The view-angle signal left in a scene, per class and band, before and after a correction.

:func:`assess_view_angles` measures the least-squares slope of reflectance against the *signed*
view zenith (:func:`signed_view_zenith`), absolute [1/deg] and relative [%/10 deg]; the ratio of
the mean reflectance on the positive side of nadir to that on the negative side
(forward/backward scattering, or right/left of the flight direction); and the across-track
profile, the mean reflectance in bins of signed view zenith. One chunk-wise pass over the before
and after cubes (dask: per-block sums, :class:`_Sums`, added in a tree, one compute).
:func:`view_angle_report` turns the result into a plain dict (NaN as ``None``, valid JSON).
"""

from __future__ import annotations

import math
import operator
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import dask
import dask.array as da
import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr

from brdfcorr._arrays import cosd, sind
from brdfcorr.analysis._assess_common import STAGES, _band_coords, _band_list, _divide, _json_numbers
from brdfcorr.defaults import MAX_BLOCK_SIZE, MIN_BIN_WIDTH, SIGN_CONVENTIONS
from brdfcorr.errors import BrdfcorrWarning, InputError

__all__ = ["SIGN_CONVENTIONS", "GROWTH_LIMIT", "signed_view_zenith", "ViewAngleOptions", "assess_view_angles",
           "error_growth_warning", "view_angle_report"]

#: The slopes' 1-sigma from blocks of twice the block size over the one reported, above which
#: :func:`assess_view_angles` warns that the errors are correlated beyond its clusters. Under
#: independent errors the ratio scatters about 1 (``benchmarks/bench_assess_coverage.py`` counts
#: how often it passes 1.25 by chance and how often correlated errors pass it).
GROWTH_LIMIT = 1.25

# SIGN_CONVENTIONS, how the sign of the view zenith is chosen (:func:`signed_view_zenith`), is
# brdfcorr.defaults' (the command line's words too).
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
    blocks: np.ndarray  # (K,) spatial blocks holding pixels of the class
    moments: np.ndarray  # (2, B, K, 5, 5) sum over blocks of v v^T, v = (n, Σθ, Σθ², ΣR, ΣθR) of a block
    blocks2: np.ndarray  # (K,) the same for blocks of twice the size
    moments2: np.ndarray  # (2, B, K, 5, 5)
    clusters: _ClusterSums  # v per (class, cluster id) of the cluster layer, added over the whole scene

    def __add__(self, other: _Sums) -> _Sums:
        return _Sums(*(getattr(self, name) + getattr(other, name) for name in self.__dataclass_fields__))


@dataclass
class _ClusterSums:
    """Per (class index, cluster id) of a cluster layer (``keys``, (L, 2)) the sums v = (n, Σθ,
    Σθ², ΣR, ΣθR) of each stage and band (``vectors``, (L, 2, B, 5)). A cluster may span dask
    blocks, so the sums are added over the scene before their outer products are taken."""

    keys: np.ndarray
    vectors: np.ndarray

    def __add__(self, other: _ClusterSums) -> _ClusterSums:
        keys, member = np.unique(np.concatenate([self.keys, other.keys]), axis=0, return_inverse=True)
        vectors = np.zeros((keys.shape[0], *self.vectors.shape[1:]))
        np.add.at(vectors, member.reshape(-1), np.concatenate([self.vectors, other.vectors]))
        return _ClusterSums(keys, vectors)


def _class_index(classes: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Index of each pixel's class in ``ids`` (sorted), -1 for other values (0, nodata, NaN)."""
    position = np.clip(np.searchsorted(ids, classes), 0, max(len(ids) - 1, 0))
    found = (ids[position] == classes) if len(ids) else np.zeros(classes.shape, bool)
    return np.where(found, position, -1)


@dataclass(frozen=True, eq=False)
class _SumOptions:
    """How :func:`_block_sums` sums a block.

    Attributes
    ----------
    ids : numpy.ndarray
        The class ids assessed, sorted.
    edges : numpy.ndarray
        Edges of the bins of signed view zenith [deg], increasing.
    by, heading :
        The sign convention and the flight direction [deg] (:func:`signed_view_zenith`).
    min_vza : float
        The smallest |signed view zenith| [deg] that counts for a side of nadir.
    flip_view_azimuth : bool
        ``vaa`` is stored as seen from the sensor: add 180 deg.
    block_size : int
        Side [pixels] of the spatial blocks of the slope's cluster-robust error (within a chunk);
        the sums are also taken over blocks of twice the size.
    cluster_nodata : float, optional
        The cluster layer's nodata value: pixels holding it (or a non-finite id) are left out.
    """

    ids: np.ndarray
    edges: np.ndarray
    by: Literal["sun", "track"]
    heading: float | None
    min_vza: float
    flip_view_azimuth: bool
    block_size: int
    cluster_nodata: float | None = None


def _spatial_blocks(valid: np.ndarray, k: np.ndarray, n_classes: int, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Each valid pixel's (class, spatial block of ``size`` pixels) group, numbered 0..G-1 in
    order, and the one-hot (G, K) matrix of the groups' classes."""
    rows, columns = np.nonzero(valid)  # the order of boolean indexing
    per_row = -(-valid.shape[1] // size)
    cells = per_row * -(-valid.shape[0] // size)
    labels, member = np.unique(k * cells + (rows // size) * per_row + columns // size, return_inverse=True)
    owner = np.zeros((labels.size, n_classes))
    owner[np.arange(labels.size), labels // cells] = 1.0
    return member.reshape(-1), owner


def _group_vectors(member: np.ndarray, size: int, s: np.ndarray, cubes) -> np.ndarray:
    """(G, 2, B, 5): per group of ``member`` (0..size-1 per valid pixel) the sums v = (n, Σθ, Σθ²,
    ΣR, ΣθR) of each stage's cube (B, valid pixels) and band."""
    vectors = np.empty((size, 2, cubes[0].shape[0], 5))
    for position, weights in enumerate((None, s, s * s)):
        vectors[..., position] = np.bincount(member, weights=weights, minlength=size)[:, None, None]
    for stage, cube in enumerate(cubes):
        for band, values in enumerate(cube):
            vectors[:, stage, band, 3] = np.bincount(member, weights=values, minlength=size)
            vectors[:, stage, band, 4] = np.bincount(member, weights=s * values, minlength=size)
    return vectors


def _moments(vectors: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """(2, B, K, 5, 5): per class (``owner``, (G, K) one-hot) the sum over its groups of v vᵀ."""
    return np.einsum("gk,gsbi,gsbj->sbkij", owner, vectors, vectors)


def _cluster_sums(clusters: np.ndarray | None, k: np.ndarray, s: np.ndarray, cubes) -> _ClusterSums:
    """:class:`_ClusterSums` of the valid pixels' cluster ids (empty without a layer)."""
    if clusters is None:
        return _ClusterSums(np.zeros((0, 2), np.int64), np.zeros((0, 2, cubes[0].shape[0], 5)))
    keys, member = np.unique(np.stack([k, clusters.astype(np.int64)], axis=1), axis=0, return_inverse=True)
    return _ClusterSums(keys, _group_vectors(member.reshape(-1), keys.shape[0], s, cubes))


def _block_sums(before, after, classes, vza, vaa, saa, clusters, options: _SumOptions) -> _Sums:
    """:class:`_Sums` of one block: cubes (band, y, x), layers (y, x), numpy."""
    ids, edges, min_vza = options.ids, options.edges, options.min_vza
    n_bands, n_classes, n_bins = before.shape[0], len(ids), len(edges) - 1
    vaa = vaa + 180.0 if options.flip_view_azimuth else vaa
    with np.errstate(invalid="ignore"):
        signed = signed_view_zenith(vza.astype(np.float64), vaa, saa, by=options.by, heading=options.heading)
        valid = (vza >= 0) & (vza < 90) & np.isfinite(signed)
    valid &= np.isfinite(before).all(axis=0) & np.isfinite(after).all(axis=0)
    if clusters is not None:
        valid &= np.isfinite(clusters)
        if options.cluster_nodata is not None:
            valid &= clusters != options.cluster_nodata
    index = _class_index(classes, ids)
    valid &= index >= 0
    k, s = index[valid], signed[valid]
    cubes = (before[:, valid].astype(np.float64), after[:, valid].astype(np.float64))
    bins = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_bins - 1)  # the last edge closes the last bin
    groups = k * n_bins + bins
    outer = np.abs(s) >= max(min_vza, np.finfo(float).tiny)  # 0 (nadir, or perpendicular) is on neither side
    sides = k[outer] * 2 + (s[outer] > 0)
    # Sums per (class, spatial block) first: the class sums are theirs added, and their outer
    # products give the slope's cluster-robust error (_cluster_error), at two block sizes.
    member, owner = _spatial_blocks(valid, k, n_classes, options.block_size)
    vectors = _group_vectors(member, owner.shape[0], s, cubes)
    member2, owner2 = _spatial_blocks(valid, k, n_classes, 2 * options.block_size)
    class_sums = np.einsum("gk,gsbi->sbki", owner, vectors)  # (2, B, K, 5)
    sums = _Sums(
        *(class_sums[0, 0, :, position] for position in range(3)), r=class_sums[..., 3], sr=class_sums[..., 4],
        bin_n=np.bincount(groups, minlength=n_classes * n_bins).astype(np.float64).reshape(n_classes, n_bins),
        bin_r=np.zeros((2, n_bands, n_classes, n_bins)),
        side_n=np.bincount(sides, minlength=n_classes * 2).astype(np.float64).reshape(n_classes, 2),
        side_r=np.zeros((2, n_bands, n_classes, 2)),
        blocks=owner.sum(axis=0), moments=_moments(vectors, owner),
        blocks2=owner2.sum(axis=0), moments2=_moments(_group_vectors(member2, owner2.shape[0], s, cubes), owner2),
        clusters=_cluster_sums(None if clusters is None else clusters[valid], k, s, cubes),
    )
    for stage, cube in enumerate(cubes):
        for band, values in enumerate(cube):
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


def _scene_sums(arrays: list, options: _SumOptions, compute: dict) -> _Sums:
    """:class:`_Sums` of whole arrays (before, after, classes, vza, vaa, saa, clusters): directly for numpy,
    per dask block and added in a tree otherwise (one compute; every block read once)."""
    if not any(isinstance(a, da.Array) for a in arrays):
        return _block_sums(*(None if a is None else np.asarray(a) for a in arrays), options)
    cube = next(a for a in arrays[:2] if isinstance(a, da.Array))
    spatial = cube.chunks[1:]
    cubes = [da.asarray(a).rechunk((-1, *spatial)).to_delayed()[0] for a in arrays[:2]]
    layers = [None if a is None else da.asarray(a).rechunk(spatial).to_delayed() for a in arrays[2:]]
    block = dask.delayed(_block_sums, pure=True)
    parts = [
        block(cubes[0][i, j], cubes[1][i, j], *(None if layer is None else layer[i, j] for layer in layers),
              options)
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


def _layer(value, name: str, shape: tuple[int, ...]):
    if value is None:
        return None
    data = value.data if isinstance(value, xr.DataArray) else value
    if tuple(np.shape(data)) != shape:
        raise InputError(f"{name} has shape {tuple(np.shape(data))}, the reflectance's grid is {shape}")
    return data


@dataclass(frozen=True)
class ViewAngleOptions:
    """How the view-angle signal is measured (:func:`assess_view_angles`); shared by
    :func:`brdfcorr.analysis.holdout.leave_one_line_out`, the files' assessments
    (:mod:`brdfcorr.tasks.assess`) and the chains' assess step.

    Attributes
    ----------
    by : {"sun", "track"}, default "sun"
        The sign convention of the view zenith (:func:`signed_view_zenith`).
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
        - ``relative_slope`` (stage, band, class): 1000 · b / R̄ [%/10 deg];
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
        One line (:func:`error_growth_warning`) where a class's 1-sigma grows with the block.

    Notes
    -----
    The slope is the ordinary least-squares estimate
    b = Σ(θ − θ̄)(R − R̄) / Σ(θ − θ̄)², computed from the sums n, Σθ, Σθ², ΣR, ΣθR of one pass as
    b = (ΣθR/n − θ̄R̄) / (Σθ²/n − θ̄²); NaN when a class is seen at one signed zenith only. A
    correction that worked leaves b ≈ 0 and a side ratio ≈ 1 in every class and band.
    """
    before, after = _check_cubes(before, after)
    by, bin_width, min_vza = options.by, options.bin_width, options.min_vza
    if by not in SIGN_CONVENTIONS:
        raise InputError(f"sign convention {by!r} is not one of {', '.join(SIGN_CONVENTIONS)}")
    if not (math.isfinite(bin_width) and MIN_BIN_WIDTH <= bin_width <= 90):
        raise InputError(f"bin width {bin_width} deg must be in [{MIN_BIN_WIDTH}, 90]")
    if not (math.isfinite(min_vza) and 0 <= min_vza < 90):
        raise InputError(f"min_vza {min_vza} deg must be in [0, 90)")
    if not (isinstance(options.block_size, int) and 1 <= options.block_size <= MAX_BLOCK_SIZE):
        raise InputError(f"block size {options.block_size} must be a whole number of pixels from 1 to {MAX_BLOCK_SIZE}")
    shape = before.shape[1:]
    layers = [_layer(value, name, shape) for name, value in
              (("the class map", classes), ("vza", vza), ("vaa", vaa), ("saa", saa), ("the cluster layer", clusters))]
    if layers[3] is None and by == "sun":
        raise InputError("the signed view zenith by the sun needs the solar azimuth (saa)")
    class_ids = options.class_ids
    ids = np.sort(np.asarray(class_ids if class_ids is not None else _present_ids(classes, _class_nodata(classes))))
    if ids.size == 0:
        raise InputError("the class map holds no class (no id > 0 outside its nodata)")
    half = math.ceil(90.0 / bin_width)
    edges = bin_width * np.arange(-half, half + 1, dtype=np.float64)
    summing = _SumOptions(ids=ids, edges=edges, by=by, heading=options.heading, min_vza=float(min_vza),
                          flip_view_azimuth=options.flip_view_azimuth, block_size=options.block_size,
                          cluster_nodata=_class_nodata(clusters))
    compute = {key: value for key, value in (("scheduler", scheduler), ("num_workers", num_workers)) if value}
    sums = _scene_sums([before.data, after.data, *layers], summing, compute)
    clustered = "the cluster layer's ids" if clusters is not None else f"square blocks of {options.block_size} pixels"
    result = _statistics(sums, ids, edges, before, options.class_names or {},
                         {"sign_convention": by, "heading": options.heading, "min_vza": float(min_vza),
                          "error_clusters": clustered}, options.block_size, clusters is not None)
    message = error_growth_warning(result)
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
    terms = (slope, mean, mean_s, n * variance)
    block_errors = np.stack([_cluster_error(sums.moments, sums.blocks, *terms),
                             _cluster_error(sums.moments2, sums.blocks2, *terms)], axis=-1)
    if clustered:
        owner = np.zeros((sums.clusters.keys.shape[0], len(ids)))
        owner[np.arange(owner.shape[0]), sums.clusters.keys[:, 0]] = 1.0
        groups = owner.sum(axis=0)
        slope_error = _cluster_error(_moments(sums.clusters.vectors, owner), groups, *terms)
    else:
        groups, slope_error = sums.blocks, block_errors[..., 0]
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
        "blocks": (("class",), groups.astype(np.int64), {"long_name": "clusters (ids or blocks) with pixels of the "
                                                                      "class", "units": "1"}),
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
        "block_size": ("block_size", [block_size, 2 * block_size], {"units": "pixel"}),
        "vza_bin": ("vza_bin", (lower + upper) / 2, {"long_name": "signed view zenith, bin centre", "units": "degree"}),
        "vza_bin_edges": (("vza_bin", "edge"), np.stack([lower, upper], axis=-1), {"units": "degree"}),
    }
    positive, negative = _SIGN_WORDS[settings["sign_convention"]]
    attrs = {**{k: v for k, v in settings.items() if v is not None}, "positive_side": positive,
             "negative_side": negative}
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _cluster_error(moments: np.ndarray, blocks: np.ndarray, slope, mean, mean_s, sxx) -> np.ndarray:
    """1-sigma of the least-squares slope [1/deg], cluster-robust over the spatial blocks (CR1,
    Liang and Zeger 1986; Cameron and Miller 2015, J. Hum. Resour. 50, 317-372, eq. 11):
    Var b = G/(G-1) Σ_g u_g² / Sxx², with u_g = Σ_{i in g} (θ_i − θ̄) e_i and the residuals
    e = R − a − bθ. u_g is linear in the block's sums v_g = (n, Σθ, Σθ², ΣR, ΣθR):
    u_g = c·v_g with c = (aθ̄, bθ̄ − a, −b, −θ̄, 1), so Σ_g u_g² = cᵀ (Σ_g v_g v_gᵀ) c. NaN with
    fewer than 2 blocks. ``moments``: (2, B, K, 5, 5), Σ_g v_g v_gᵀ per class; ``blocks``: (K,) G."""
    intercept = mean - slope * mean_s
    c = np.stack(np.broadcast_arrays(intercept * mean_s, slope * mean_s - intercept, -slope, -mean_s,
                                     np.ones_like(slope)), axis=-1)
    scores = np.maximum(np.einsum("...i,...ij,...j->...", c, moments, c), 0.0)
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
            "correlated beyond them and the 1-sigma is too small; give a cluster layer of the units that share "
            "errors (--clusters: a composite's day-of-year band, a flight-line id) or a larger --block-size")


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

    Per class: id, name, pixels, blocks (the clusters of the 1-sigma), ``error_growth`` (the
    median over bands of the 1-sigma's growth to blocks of twice the size, after the correction),
    ``bands_within_2_sigma`` (how many of its bands' slopes
    lie within 2 sigma of 0: ``before``, ``after``, ``of``) and per stage the per band lists of
    ``mean`` [1], ``slope`` [1/deg], ``relative_slope``, ``relative_slope_error`` and
    ``relative_slope_error_double_block`` (over blocks of twice the block size) [%/10 deg] and
    ``side_ratio`` [-]; the profile (bin edges [deg], pixels, mean per band and bin).
    ``summary``: median and largest |relative slope| and |side ratio − 1| [%] over classes and
    bands, before and after, and how many class-band slopes lie within 2 sigma of 0
    (``slopes_within_2_sigma``: ``before``, ``after``, ``of``). ``errors``: what the 1-sigma is
    cluster-robust over, the two block sizes [pixels] and the warning of
    :func:`error_growth_warning` (or None).
    """
    growth = _class_growth(dataset)
    classes = []
    for index, class_id in enumerate(dataset["class"].values):
        one = dataset.isel({"class": index})
        entry: dict[str, object] = {"id": int(class_id), "name": str(one["class_name"].values),
                                    "pixels": int(one["pixels"]), "blocks": int(one["blocks"]),
                                    "error_growth": _json_numbers(growth[index])}
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
                   "warning": error_growth_warning(dataset)},
        "bands": _band_list(dataset),
        "classes": classes,
        "summary": {"abs_relative_slope_percent_per_10deg": _stage_summary(dataset["relative_slope"]),
                    "slopes_within_2_sigma": _within_two_sigma(dataset),
                    "abs_side_ratio_minus_1_percent": _stage_summary(100.0 * (dataset["side_ratio"] - 1.0))},
    }
