"""Pooling and sampling the pixels of each class from one or many scenes (for :mod:`brdfcorr.fit.classes`)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse
import scipy.sparse.csgraph
import xarray as xr

from brdfcorr._validation import check_flags
from brdfcorr.correction.checks import (
    ANGLE_LAYERS,
    as_dataarray,
    check_grid,
    check_layout,
    guard_angles,
)
from brdfcorr.correction.series import dated_like
from brdfcorr.defaults import LEVELS
from brdfcorr.errors import BrdfcorrWarning, InputError, ParameterError
from brdfcorr.fit.grids import CommonGrid, common_grid
from brdfcorr.fit.settings import Sampling
from brdfcorr.geometry import relative_azimuth
from brdfcorr.io.grid import describe_layer
from brdfcorr.io.reflectance import carries_scale, declared_nodata, reflectance_factors, unpacked
from brdfcorr.io.wavelengths import matched_bands, with_wavelengths
from brdfcorr.io.writer import local_scheduler

__all__ = ["LEVELS", "ClassSamples", "nested_clusters", "resolve_levels", "sample_classes", "scene_lists"]


@dataclass
class ClassSamples:
    """The pooled, sampled pixels of one class: angles [deg] and BRDF [sr^-1] per band."""

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    brdf: np.ndarray  # (N, B)
    block: np.ndarray | None = None  # spatial block (or cluster layer) id of each sample (cluster for the errors)
    group: np.ndarray | None = None  # the pixel or patch whose level is free (LEVELS), if any
    scene: np.ndarray | None = None  # the scene each sample comes from (its level is free too)
    levels: str = "pooled"  # whose levels are free (LEVELS, resolved)
    note: str | None = None  # how the scenes were brought onto one grid, if they were
    scene_errors: bool = False  # errors two-way cluster-robust, over ``block`` and ``scene`` (fit.two_way)
    empty_bands: tuple[int, ...] = ()  # bands (0-based) not finite at any sampled pixel: no sample is left
    empty_reason: str | None = None  # ... named, with the pixels sampled: why the class cannot be fitted

    def finite(self, notes: list[str]) -> ClassSamples:
        """These samples without those whose angles or BRDF (in any band) are not finite, with a note
        in ``notes`` of how many (samples given in Python: the sampler keeps finite ones only). A
        NaN in one band's samples gave that band zero intensities and dropped the class's errors."""
        if not np.size(self.theta_i):
            return self
        brdf = np.reshape(self.brdf, (np.size(self.theta_i), -1))
        keep = np.isfinite(np.column_stack([self.theta_i, self.theta_r, self.phi, brdf])).all(axis=1)
        if keep.all():
            return self
        notes.append(f"{keep.size - keep.sum()} of {keep.size} samples left out: a non-finite angle or BRDF")
        per_sample = {name: getattr(self, name) for name in ("theta_i", "theta_r", "phi", "brdf", "block", "group",
                                                              "scene")}
        return replace(self, **{name: None if value is None else np.asarray(value)[keep]
                                for name, value in per_sample.items()})


def _in_memory(array, dtype=None) -> np.ndarray:
    """The values of a layer (numpy, or dask computed on the local scheduler without importing
    dask.distributed, :func:`brdfcorr.io.writer.local_scheduler`; on a current Client where there is one)."""
    data = array.data if isinstance(array, xr.DataArray) else array
    compute = getattr(data, "compute", None)
    return np.asarray(compute(scheduler=local_scheduler(None)) if compute is not None else data, dtype=dtype)


def _class_values(class_map: xr.DataArray) -> np.ndarray:
    """The class ids of a class map in memory, its nodata (:func:`~brdfcorr.io.reflectance.declared_nodata`) read
    as 0, "no class"."""
    values = _in_memory(class_map)
    nodata = declared_nodata(class_map)
    return np.where(values == nodata, 0, values) if nodata is not None else values


def _as_list(value) -> list:
    return list(value) if isinstance(value, (list, tuple)) else [value]


def scene_lists(images, classes, angles, clusters=None, dim: str = "time") -> tuple[list, list, list, object]:
    """One image, class map and angle set per scene: lists as given, or a cube with a ``dim``
    dimension (a time series) as one scene per date, its class map and angles per date where they
    have that dimension and the same for every date where they have not; and the cluster layers
    (``clusters`` as given, a layer with that dimension one per date). Dated layers take the
    cube's dates by label where both have them (a cluster layer was paired by position)."""
    if not isinstance(images, xr.DataArray) or dim not in images.dims:
        return _as_list(images), _as_list(classes), _as_list(angles), clusters
    cube = images.transpose(dim, ...)
    count = cube.sizes[dim]

    def per_date(value, name: str | None = None) -> list:
        if isinstance(value, (xr.DataArray, xr.Dataset)) and dim in value.dims:
            if name is not None:  # the image's dates, by label where both have them
                value = dated_like(value, cube, name)
            return [value.isel({dim: index}, drop=True) for index in range(count)]
        return [value] * count

    dated = isinstance(clusters, xr.DataArray) and dim in clusters.dims
    return (per_date(cube), per_date(classes, "class map"), per_date(angles, "angles"),
            per_date(clusters, "cluster layer") if dated else clusters)


def _checked(images: list, classes: list, angles: list, sampling: Sampling) -> tuple[list, list, list]:
    """The images as reflectance factors, the class maps and the angle sets on their images'
    grids, the angles unpacked and guarded, as :func:`brdfcorr.correction.normalize` checks its
    inputs (:mod:`brdfcorr.correction.checks`): bands last refused, each layer on its image's grid
    (:func:`~brdfcorr.correction.checks.check_grid`: the sampler pairs the layers pixel by pixel),
    integer counts scaled with the scale they carry (or by the sampling's ``reflectance_scale``,
    not both), a declared nodata as NaN, packed angles (int16 hundredths with a ``scale_factor``)
    in degrees, and view azimuths stored as seen from the sensor turned by 180 deg (the sampling's
    ``flip_view_azimuth``), and each scene's bands paired with the first scene's by their
    wavelengths where both have them (:func:`~brdfcorr.io.wavelengths.matched_bands`: a file whose
    bands are stored in another order is read in the first's; other bands, or another count, are
    an :class:`~brdfcorr.errors.InputError`)."""
    check_flags(flip_view_azimuth=sampling.flip_view_azimuth)
    reflectance_scale = sampling.reflectance_scale
    checked_images, checked_classes, checked_angles = [], [], []
    for image, class_map, angle_set in zip(images, classes, angles):
        image = as_dataarray(image, "image", ("band", "y", "x"))
        layers = {name: angle_set[name] for name in ANGLE_LAYERS if name in angle_set}
        check_layout(image, [class_map, *layers.values()])
        if image.dims != ("band", "y", "x"):  # 'bands', 'lat'/'lon' (as normalize takes them): the sampler's names
            image = image.rename(dict(zip(image.dims, ("band", "y", "x"))))
        spatial = image.dims[1:]
        checked_classes.append(check_grid(image, "classes", as_dataarray(class_map, "classes", spatial)))
        layers = {name: check_grid(image, name, as_dataarray(layer, name, spatial)) for name, layer in layers.items()}
        if reflectance_scale != 1.0 and image.dtype.kind in "iu" and carries_scale(image):
            scale = {**image.encoding, **image.attrs}["scale_factor"]
            raise ParameterError(f"the image's counts carry scale_factor={scale} and the sampling's reflectance_scale="
                                 f"{reflectance_scale:g} would scale them again: give one of the two")
        checked_images.append(reflectance_factors(image, unscaled_counts=reflectance_scale != 1.0))
        if len(layers) == len(ANGLE_LAYERS):  # else the sampler names what is missing
            layers = {name: unpacked(layer, name) if isinstance(layer, xr.DataArray) else layer
                      for name, layer in layers.items()}
            replaced = {**layers, "sza": guard_angles(layers)["sza"]}
            if sampling.flip_view_azimuth:
                replaced["vaa"] = layers["vaa"] + 180.0
            angle_set = (angle_set.assign(replaced) if isinstance(angle_set, xr.Dataset)
                         else {**angle_set, **replaced})
        checked_angles.append(angle_set)
    first = with_wavelengths(checked_images[0])
    checked_images = [first] + [
        matched_bands(with_wavelengths(image), first, (describe_layer(f"scene {number}", image),
                                                       describe_layer("scene 1", first)))
        for number, image in enumerate(checked_images[1:], start=2)]
    return checked_images, checked_classes, checked_angles


def _scene_samples(scene: int, image, angle_set, shape, flat, reflectance_scale: float, block_size: int,
                   shared_grid: bool = False, cluster_ids: np.ndarray | None = None,
                   read_at: np.ndarray | None = None) -> tuple:
    """The samples of one scene (number ``scene``) at the flat pixel indices ``flat`` of its class
    map (of ``shape`` (y, x)): sun zenith, view zenith and relative azimuth [deg], BRDF (N, B)
    [sr^-1], and the id of each sample's spatial block of ``block_size`` pixels (unique over the
    scenes; on a ``shared_grid`` the same in every scene, so that a block holds every view of its
    ground), or, given the scene's ``cluster_ids`` (y, x; integer-valued), each sample's id there.
    Stored values times ``reflectance_scale`` are reflectance factors. With ``read_at`` (flat
    indices into the scene's own grid) the class map's grid is a common grid
    (:mod:`brdfcorr.fit.grids`) and the values are read at those pixels of the scene."""
    iy, ix = np.unravel_index(flat, shape)
    ry, rx = (iy, ix) if read_at is None else np.unravel_index(read_at, (image.sizes["y"], image.sizes["x"]))
    where = {"y": xr.DataArray(ry, dims="sample"), "x": xr.DataArray(rx, dims="sample")}

    def pick(array):
        # Pointwise (vectorized) indexing: lazy on dask, reads only the sampled pixels.
        return _in_memory(array.isel(where), float)

    reflectance = pick(image.transpose("band", "y", "x")).T * reflectance_scale
    saa, vaa = pick(angle_set["saa"]), pick(angle_set["vaa"])
    if cluster_ids is not None:
        labels = cluster_ids[iy, ix].astype(np.int64)
    else:
        blocks_x = -(-shape[1] // block_size)
        block = (0 if shared_grid else scene, iy // block_size, ix // block_size)
        labels = (block[0] * 10**9 + block[1] * blocks_x + block[2]).astype(np.int64)
    return (pick(angle_set["sza"]), pick(angle_set["vza"]), relative_azimuth(saa, vaa), reflectance / math.pi,
            labels)


def _band_names(indices, image) -> str:
    """Bands by number (1-based) and, where the image has them, wavelength [nm]; five at most."""
    wavelengths = image.coords["wavelength"].values if "wavelength" in image.coords else None
    names = [f"band {index + 1}" + (f" ({float(wavelengths[index]):g} nm)" if wavelengths is not None else "")
             for index in indices[:5]]
    return ", ".join(names) + (f" and {len(indices) - 5} more" if len(indices) > 5 else "")


def _check_bands(pooled: dict[int, ClassSamples], image) -> None:
    """Refuse a band that is not finite at any sampled pixel of any class: every sample of every
    class would be dropped, and the band is bad for the whole image. A band empty in some classes
    only fails those classes (``ClassSamples.empty_bands``, their guard rails)."""
    sampled = [samples for samples in pooled.values() if samples.empty_bands or samples.theta_i.size]
    empty = sorted(set.intersection(*(set(samples.empty_bands) for samples in sampled))) if sampled else []
    if empty:
        raise InputError(f"{_band_names(empty, image)}: no finite reflectance at any sampled pixel of any class "
                         f"({len(sampled)} classes; all NaN, inf or nodata); leave the band out of the image")


def sample_classes(images, classes, angles, *, class_ids: Sequence[int] | None = None, sampling: Sampling = Sampling(),
                   clusters=None, min_repeated: int = 500, dates: bool = False) -> dict[int, ClassSamples]:
    """Pool each class's valid pixels over one or many scenes and sample them reproducibly.

    Parameters
    ----------
    images : DataArray or list of DataArray, dims (band, y, x)
        Reflectance factors (numpy- or dask-backed); the band count must agree across scenes. A
        cube with a ``time`` dimension (time, band, y, x) is one scene per date
        (:func:`scene_lists`).
    classes : DataArray or list of DataArray, dims (y, x)
        Integer class maps on the images' grids; 0, negative values and the map's nodata
        (``.rio.nodata``) mean "no class".
    angles : Dataset or list of Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on the images' grids (docs/conventions.md).
    class_ids : sequence of int, optional
        Classes to sample (default: every positive id found).
    sampling : Sampling, default Sampling()
        The sampler's settings (:class:`brdfcorr.fit.settings.Sampling`; its ``keep_samples``,
        ``bad_bands`` and ``errors_cluster`` are the fit's): ``max_samples`` per class over all
        scenes together (without replacement, from ``seed``), the ``reflectance_scale``, the
        ``block_size`` [pixels] of the square spatial blocks whose ids label the samples
        (``ClassSamples.block``; on scenes that share one grid a block is the same ground in every
        scene), and whose level the fit leaves free (``levels``, :data:`LEVELS`,
        :mod:`brdfcorr.fit.within`): with ``pixel`` or ``patch`` (of ``patch_size`` pixels, a
        divisor of ``block_size``) whole groups (a pixel's views in every scene; a patch's pixels)
        are sampled, groups with a single view left out, and every sample carries its group and
        scene (``ClassSamples.group``, ``.scene``); ``pixel`` needs several scenes, ``auto`` frees
        the pixels' levels where several scenes share ground and pools a single scene. Scenes on
        different grids (overlapping flight lines) are brought onto one common grid for ``pixel``
        and ``patch`` (and for ``auto``, for each class whose views of pixels seen twice or more
        number ``min_repeated`` at least; other classes are pooled): the first scene's CRS and
        pixel grid over the union of their extents, nearest neighbour (:mod:`brdfcorr.fit.grids`;
        each class's ``ClassSamples.note`` says how many of its pixels are seen twice or more).
    clusters : DataArray or array (y, x), or a list of them, optional
        Instead of square blocks, a cluster layer per scene (one for every scene, or a list in
        the scenes' order) on its grid: integer ids of the units whose pixels share their errors
        (a composite's day-of-year band, a flight-line or detector id), each sample's
        ``ClassSamples.block``. An id is one cluster over all scenes (a detector's pixels in
        every scene; number the scenes' ids apart to keep them apart). Pixels with a non-finite
        id or the layer's rioxarray nodata are not sampled. With free levels, clusters that share
        a group (a pixel's or patch's views) are merged into one (:func:`nested_clusters`): a
        group's level is estimated from all its views.
    min_repeated : int, default 500
        With ``levels="auto"`` over scenes on different grids: the fewest views of pixels seen
        twice or more for a class to be sampled within pixels on the common grid (fewer: pooled,
        on the scenes' own grids). :func:`brdfcorr.fit.fit_classes` passes its guard rail's
        ``min_samples``.
    dates : bool, default False
        The scenes are the dates of one cube, split by the caller (one grid by construction):
        scenes without a CRS taken as one grid are then no warning.

    Returns
    -------
    dict of int to ClassSamples
        BRDF = reflectance / pi [sr^-1]. Samples whose reflectance is not finite in some band are
        dropped after sampling, so a class may end up with fewer than ``max_samples``.

    Raises
    ------
    InputError
        A band without a finite value at any sampled pixel of any class (named by number and
        wavelength): bad for the whole image. A band empty in some classes only leaves those
        without samples (``ClassSamples.empty_bands``; their fits fail, naming the band).
    ParameterError
        Cluster layers: not one per scene, not on a scene's grid, or ids that are not integers.

    Notes
    -----
    Only the class maps and the angle layers needed to find valid pixels are computed whole; the
    reflectance is read at the sampled pixels only (pointwise indexing stays lazy on dask), on
    the scenes' own grids also where they were brought onto a common grid.
    """
    cube = dates or (isinstance(images, xr.DataArray) and "time" in images.dims)  # one grid by construction
    images, classes, angles, clusters = scene_lists(images, classes, angles, clusters)
    if not len(images) == len(classes) == len(angles):
        raise ParameterError(
            f"{len(images)} images, {len(classes)} class maps and {len(angles)} angle sets: "
            "give one class map and one angle set per image"
        )
    images, classes, angles = _checked(images, classes, angles, sampling)
    maps = [_class_values(class_map) for class_map in classes]
    cluster_ids = _cluster_ids(clusters, [m.shape for m in maps])
    valid_angles = [
        np.all([np.isfinite(_in_memory(a[name])) for name in ("sza", "saa", "vza", "vaa")], axis=0)
        for a in angles
    ]
    if cluster_ids is not None:
        valid_angles = [ok & np.isfinite(ids) for ok, ids in zip(valid_angles, cluster_ids)]
    if class_ids is None:
        class_ids = sorted({int(c) for m in maps for c in np.unique(m) if c > 0})
    own = _Layers(maps, valid_angles, cluster_ids, _shared_grid(images, maps))
    levels, patch_size, block_size = sampling.levels, sampling.patch_size, sampling.block_size
    common = None
    if not own.shared and len(images) > 1 and levels in ("pixel", "patch", "auto"):
        grid = _common_grid(images, levels)
        if grid is not None:
            common = own.on_grid(grid, resolve_levels(levels, len(images), True, patch_size, block_size))
    if common is None or levels == "auto":
        own.levels = resolve_levels(levels, len(images), own.shared, patch_size, block_size)
    if own.shared and own.levels != "pooled" and not cube and not any(image.rio.crs is not None for image in images):
        warnings.warn(BrdfcorrWarning(
            f"the {len(images)} scenes have no CRS: taken as one grid by their shape (and coordinates), each pixel "
            f"the same ground in every scene, with its level free ({own.levels}); give them their CRS, or levels "
            "'pooled' if they are other ground"), stacklevel=3)
    rng = np.random.default_rng(sampling.seed)
    pooled: dict[int, ClassSamples] = {}
    for class_id in class_ids:
        within = common is not None and (levels != "auto" or common.repeated_views(class_id) >= min_repeated)
        layers = common if within and common is not None else own
        pooled[class_id] = _sample_class(class_id, images, angles, layers, rng, sampling)
    _check_bands(pooled, images[0])
    return pooled


@dataclass
class _Layers:
    """What the sampler holds whole of every scene: class ids, valid angles (and cluster ids)
    (y, x), on one grid (``shared``; a ``grid`` they were brought onto, if they were) or each on
    its scene's own; and the levels (:data:`LEVELS`, resolved) sampled from them."""

    maps: list[np.ndarray]
    valid: list[np.ndarray]
    cluster_ids: list[np.ndarray] | None
    shared: bool
    levels: str = "pooled"
    grid: CommonGrid | None = None

    def on_grid(self, grid: CommonGrid, levels: str) -> _Layers:
        """The layers gathered onto the common ``grid`` (nearest neighbour, :mod:`brdfcorr.fit.grids`),
        each over its scene's window only (:class:`brdfcorr.fit.grids.WindowLayer`)."""
        clusters = self.cluster_ids
        return _Layers([grid.gather(scene, m, 0) for scene, m in enumerate(self.maps)],
                       [grid.gather(scene, ok, False) for scene, ok in enumerate(self.valid)],
                       None if clusters is None else [grid.gather(scene, ids, np.nan)
                                                      for scene, ids in enumerate(clusters)],
                       True, levels, grid)

    def candidates(self, class_id: int) -> list[np.ndarray]:
        """Per scene, the flat indices (of the common grid, if there is one) of the class's valid pixels."""
        if self.grid is not None:  # windowed layers
            return [m.flat_where((m.values == class_id) & ok.values) for m, ok in zip(self.maps, self.valid)]
        return [np.flatnonzero((m == class_id) & ok) for m, ok in zip(self.maps, self.valid)]

    def repeated_views(self, class_id: int) -> int:
        """The class's views of pixels seen by two or more scenes (on a shared grid)."""
        if self.grid is not None:
            _, seen = np.unique(np.concatenate(self.candidates(class_id)), return_counts=True)
            return int(seen[seen >= 2].sum())
        seen = np.sum([(m == class_id) & ok for m, ok in zip(self.maps, self.valid)], axis=0)
        return int(seen[seen >= 2].sum())


def _sample_class(class_id: int, images: list, angles: list, layers: _Layers, rng,
                  sampling: Sampling) -> ClassSamples:
    """One class's samples (:func:`sample_classes`) from the ``layers``, as ``sampling`` says
    (the most samples, the reflectance scale, the block and patch sizes)."""
    max_samples = sampling.max_samples
    candidates = layers.candidates(class_id)
    groups: list[np.ndarray | None] = [None] * len(images)
    if layers.levels == "pooled":
        chosen = _pooled_choice(candidates, max_samples, rng)
    else:
        patch = 1 if layers.levels == "pixel" else sampling.patch_size
        groups = [_group_of(flat, m.shape, patch, None if layers.shared else scene)
                  for scene, (flat, m) in enumerate(zip(candidates, layers.maps))]
        chosen = _grouped_choice(groups, max_samples, rng)
    selected = [(candidates[scene][chosen[scene]], None if groups[scene] is None else groups[scene][chosen[scene]])
                for scene in range(len(images))]
    parts = _scene_parts(images, angles, layers.maps, selected,
                         (sampling.reflectance_scale, sampling.block_size, layers.shared),
                         layers.cluster_ids, layers.grid)
    samples = _class_samples(parts, images[0], class_id, layers.levels)
    samples.note = None if layers.grid is None else _grid_note(candidates, layers.grid.shape)
    if layers.cluster_ids is not None and samples.group is not None and samples.block is not None \
            and samples.block.size:
        samples.block = nested_clusters(samples.block, samples.group)
    return samples


def _cluster_ids(clusters, shapes: list[tuple[int, ...]]) -> list[np.ndarray] | None:
    """Each scene's cluster ids (float (y, x): NaN where none, at the layer's nodata), from one
    layer for every scene or a list of one per scene; None without a layer. ParameterError where
    the layers do not match the scenes or hold ids that are not integers."""
    if clusters is None:
        return None
    if isinstance(clusters, xr.DataArray) and "time" in clusters.dims:  # one layer per date of a cube
        clusters = [clusters.isel(time=index, drop=True) for index in range(clusters.sizes["time"])]
    layers = list(clusters) if isinstance(clusters, (list, tuple)) else [clusters] * len(shapes)
    if len(layers) != len(shapes):
        raise ParameterError(f"{len(layers)} cluster layers for {len(shapes)} scenes: give one per scene, or one "
                             "for every scene")
    found = []
    for scene, (layer, shape) in enumerate(zip(layers, shapes)):
        nodata = declared_nodata(layer) if isinstance(layer, xr.DataArray) else None
        ids = _in_memory(layer, float)
        if ids.shape != tuple(shape):
            raise ParameterError(f"the cluster layer of scene {scene + 1} has shape {ids.shape}, its class map "
                                 f"{tuple(shape)}: give a layer on the scene's grid")
        if nodata is not None:
            ids = np.where(ids == nodata, np.nan, ids)
        finite = ids[np.isfinite(ids)]
        if np.any(finite != np.round(finite)):
            raise ParameterError(f"the cluster layer of scene {scene + 1} holds ids that are not integers: give "
                                 "integer ids (a day-of-year band, a flight-line id)")
        found.append(ids)
    return found


def nested_clusters(clusters: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Cluster ids (N,) coarsened so that every group (N,; a pixel or patch whose level is free)
    lies in one cluster: clusters that share a group are merged, transitively (the connected
    components of the graph linking each sample's cluster to its group). Ids 0..C-1; unchanged
    partitions where the clusters hold whole groups already (square blocks of whole patches)."""
    _, cluster_index = np.unique(clusters, return_inverse=True)
    _, group_index = np.unique(groups, return_inverse=True)
    cluster_index, group_index = cluster_index.reshape(-1), group_index.reshape(-1)
    n_clusters = int(cluster_index.max(initial=-1)) + 1
    size = n_clusters + int(group_index.max(initial=-1)) + 1
    links = scipy.sparse.coo_matrix((np.ones(cluster_index.size), (cluster_index, n_clusters + group_index)),
                                    shape=(size, size))
    _, component = scipy.sparse.csgraph.connected_components(links, directed=False)
    return component[cluster_index].astype(np.int64)


def _scene_parts(images: list, angles: list, maps: list[np.ndarray], selected: list[tuple], reading: tuple,
                 cluster_ids: list[np.ndarray] | None, grid: CommonGrid | None = None) -> list[tuple]:
    """Each scene's part of one class's samples (:func:`_scene_samples`: angles [deg], BRDF [sr^-1],
    block or cluster id; with groups also the group; and the scene of each sample) at its
    ``selected`` pixels (flat indices into the scene's grid, or the common ``grid``'s, and their
    groups or None); scenes without any are skipped. ``reading``: the reflectance scale, block
    size and whether the scenes share one grid."""
    reflectance_scale, block_size, shared = reading
    parts = []
    for scene, ((flat, group), image, angle_set) in enumerate(zip(selected, images, angles)):
        if flat.size:
            values = _scene_samples(scene, image, angle_set, maps[scene].shape, flat, reflectance_scale,
                                    block_size, shared, None if cluster_ids is None else cluster_ids[scene],
                                    None if grid is None else grid.source_pixels(scene, flat))
            labels = () if group is None else (group,)
            parts.append((*values, *labels, np.full(flat.size, scene)))
    return parts


def _class_samples(parts: list[tuple], image, class_id: int, levels: str) -> ClassSamples:
    """One class's samples from the scenes' parts (angles, BRDF, block[, group], scene), without
    the samples that are not finite in some band (the bands finite at none named in
    ``empty_bands`` and ``empty_reason``); pooled samples keep their scene too (for errors
    clustered by scene, :mod:`brdfcorr.fit.two_way`)."""
    grouped = levels != "pooled"
    if not parts:
        empty = np.empty(0, np.int64)
        arrays = [*(np.empty(0) for _ in range(3)), np.empty((0, image.sizes["band"])), empty,
                  *((empty,) if grouped else ()), empty]
    else:
        arrays = [np.concatenate(p) for p in zip(*parts)]
        finite = np.isfinite(arrays[3])
        empty = tuple(int(band) for band in np.flatnonzero(~finite.any(axis=0)))
        keep = np.all(finite, axis=1)
        arrays = [a[keep] for a in arrays]
    samples = ClassSamples(*arrays[:5], group=arrays[5] if grouped else None, scene=arrays[-1], levels=levels)
    if parts and empty:
        samples.empty_bands = empty
        samples.empty_reason = (f"{_band_names(empty, image)}: no finite reflectance at any of the class's "
                                f"{keep.size} sampled pixels (all NaN, inf or nodata)")
    return samples


def _common_grid(images: list, levels: str) -> CommonGrid | None:
    """The common grid of scenes on different grids (:func:`brdfcorr.fit.grids.common_grid`), or
    None where they are not georeferenced and ``levels`` is ``auto`` (pooled) or ``patch`` (each
    scene's own patches); ParameterError for ``pixel``."""
    try:
        return common_grid(images)
    except ParameterError:
        if levels == "pixel":
            raise
        return None


def _grid_note(candidates: list[np.ndarray], shape: tuple[int, int]) -> str:
    """How many of a class's pixels of the common grid (of ``shape``) the scenes' ``candidates``
    (flat indices) see twice or more, and how many once (they drop out of a within fit)."""
    seen = np.unique(np.concatenate(candidates), return_counts=True)[1] if candidates else np.zeros(1)
    twice, once = int(np.count_nonzero(seen >= 2)), int(np.count_nonzero(seen == 1))
    return (f"scenes on different grids resampled (nearest neighbour) onto the first scene's grid over their "
            f"union ({shape[0]} x {shape[1]} pixels): {twice} of the class's pixels seen by two or more scenes, "
            f"{once} seen once (left out of the within fit)")


def _shared_grid(images, maps) -> bool:
    """Whether every scene lies on one grid: class maps of one shape and, where the images have
    them, one CRS and the same x and y coordinates (the same numbers in two UTM zones are ground
    600 km apart)."""
    if len({m.shape for m in maps}) != 1:
        return False
    crs = {image.rio.crs for image in images if image.rio.crs is not None}
    if len(crs) > 1:
        return False
    for name in ("x", "y"):
        coords = [np.asarray(image[name].values) for image in images if name in image.coords]
        if coords and not all(c.shape == coords[0].shape and np.allclose(c, coords[0]) for c in coords):
            return False
    return True


def resolve_levels(levels: str, n_scenes: int, shared: bool, patch_size: int, block_size: int) -> str:
    """The levels a fit uses (:data:`LEVELS`; ``auto`` resolved), or a ParameterError saying why
    they cannot be."""
    if levels not in LEVELS:
        raise ParameterError(f"levels {levels!r}: use one of {', '.join(LEVELS)}")
    if levels == "auto":
        return "pixel" if shared and n_scenes > 1 else "pooled"
    if levels == "pixel" and not (shared and n_scenes > 1):
        raise ParameterError("free levels per pixel need several scenes on one grid, or georeferenced scenes "
                             "that overlap (the same ground seen more than once): use levels per patch")
    if levels == "patch" and (patch_size < 1 or block_size % patch_size):
        raise ParameterError(f"patch size {patch_size}: it must be a positive divisor of the block size "
                             f"{block_size} (a block holds whole patches)")
    return levels


def _group_of(flat: np.ndarray, shape, patch: int, scene: int | None) -> np.ndarray:
    """The group (patch of ``patch`` x ``patch`` pixels) of each flat pixel index of a grid of
    ``shape``; unique to the scene unless ``scene`` is None (one grid shared by the scenes)."""
    iy, ix = np.unravel_index(flat, shape)
    per_row = -(-shape[1] // patch)
    label = (iy // patch) * per_row + ix // patch
    return label if scene is None else label + scene * per_row * -(-shape[0] // patch)


def _pooled_choice(candidates: list[np.ndarray], max_samples: int, rng) -> list[np.ndarray]:
    """Per scene, the positions (sorted) in its candidates of at most ``max_samples`` candidates
    drawn without replacement over all scenes together."""
    offsets = np.concatenate([[0], np.cumsum([c.size for c in candidates])])
    chosen = np.sort(rng.choice(offsets[-1], size=min(max_samples, offsets[-1]), replace=False))
    return [chosen[(chosen >= low) & (chosen < high)] - low for low, high in zip(offsets[:-1], offsets[1:])]


def _grouped_choice(groups: list, max_samples: int, rng) -> list[np.ndarray]:
    """Per scene, the positions of the candidates in whole groups drawn at random among those
    with two or more candidates over all scenes, until ``max_samples`` are reached."""
    labels, counts = np.unique(np.concatenate(groups), return_counts=True)
    labels, counts = labels[counts >= 2], counts[counts >= 2]
    order = rng.permutation(labels.size)
    taken = labels[order[:np.searchsorted(np.cumsum(counts[order]), max_samples, side="right")]]
    return [np.flatnonzero(np.isin(group, taken)) for group in groups]
