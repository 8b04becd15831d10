"""The imagery fit on files that the CLI and chains share: :func:`fit_class_files` fits per-class
parameters from scenes (``brdfcorr fit-classes``, a chain's imagery fit).

It reads files but prints nothing: the CLI shows its result, chains report it. Warnings of the
fits are collected into the result (``warnings``), one line each. A goniometer table's fit is
:mod:`brdfcorr.tasks.goniometer` (its names are importable from here too); the correction of an
image file is :func:`brdfcorr.tasks.correct.correct_files`.
"""

from __future__ import annotations

import concurrent.futures
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import xarray as xr

from brdfcorr._entry import option
from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.fit.classes import ClassFitResult, ClassFitWarning, ClassModels, GuardRails, Sampling, fit_classes
from brdfcorr.fit.settings import DEFAULT_MODEL, STRATA_MODEL
from brdfcorr.io import rasters, scale_check
from brdfcorr.io.scene import SceneData, SceneSources, open_scene
from brdfcorr.io.sensors.envi import envi_bad_bands
from brdfcorr.params import ParameterTable
from brdfcorr.params.bands import in_ranges
from brdfcorr.tasks.classmaps import class_preparation, tagged_class_names
from brdfcorr.tasks.goniometer import MeasurementFit, fit_measurement_file
from brdfcorr.tasks.pool import process_pool

__all__ = [
    "fit_measurement_file",  # these two: brdfcorr.tasks.goniometer's, re-exported from their home before
    "MeasurementFit",
    "fit_class_files",
    "SceneFiles",
    "ImageryFitResult",
]


# ------------------------------------------------------------------------------ imagery fit
@dataclass(frozen=True)
class SceneFiles(SceneSources):
    """One scene of an imagery fit: its files as for a correction (:class:`~brdfcorr.io.scene.SceneSources`:
    image, class map, angle source and how to read them; ``scale``/``offset``: the image's, None for
    the file's), its name in messages and how its class map is prepared (as for
    :func:`~brdfcorr.tasks.correct.correct_files`).

    Attributes
    ----------
    name : str
        The scene's name in the report of scenes left out (default: :attr:`image_label`).
    align_classes : bool
        Bring the class map onto the image grid (nearest neighbour) instead of refusing another grid.
    class_lookup : mapping of int to int, optional
        Class ids of the map replaced by the table's (e.g. land-cover codes to classes).
    clusters : (path-like, int), optional
        A raster on the image's grid and its band (from 1) of integer ids of the units whose
        pixels share their errors (a composite's day-of-year band, a flight-line id): the fit's
        errors are cluster-robust over these instead of square blocks (every scene needs one then).
    """

    name: str = ""
    align_classes: bool = False
    class_lookup: Mapping[int, int] | None = None
    clusters: tuple[str | os.PathLike, int] | None = None


@dataclass(frozen=True)
class ImageryFitResult:
    """The result of :func:`fit_class_files`: the fit, the scenes used and those left out.

    ``wavelengths`` [nm] are those of the fitted bands (the bad bands left out), in the images'
    order; ``notes`` say, one line each, what was chosen for the user: the model taken from the
    class maps (NDVI strata), class names read from their tags, bad bands left out of the fit.
    """

    result: ClassFitResult
    scenes: list[SceneFiles]
    wavelengths: np.ndarray | None
    left_out: list[dict[str, str]] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def table(self) -> ParameterTable:
        return self.result.table

    def report(self) -> dict:
        """JSON-friendly: the classes' fits, scenes left out, bad bands, notes and warnings."""
        return {
            "source": "imagery", "scenes": len(self.scenes), "scenes_left_out": self.left_out,
            "classes": self.result.report(), "bad_bands": self.result.bad_bands,
            "bands_left_out": self.result.bands_left_out, "notes": list(self.notes),
            "warnings": list(self.warnings),
        }


#: Tag values of the ``strata`` tag of an NDVI strata map (``brdfcorr classes ndvi``).
_STRATA_TAGS = ("ndvi_edges", "ndvi_percentiles")


def _is_strata(classes: xr.DataArray) -> bool:
    """Whether a class map is NDVI strata (vegetation and soil), by the tags ``classes ndvi`` writes."""
    return classes.attrs.get("strata") in _STRATA_TAGS or str(classes.attrs.get("brdf_class_map", "")).startswith(
        "NDVI strata")


def _choices_from_maps(models: ClassModels, class_maps: Sequence[xr.DataArray]) -> tuple[ClassModels, list[str]]:
    """``models`` with the model chosen from the class maps where none was given (NDVI strata:
    :data:`STRATA_MODEL`, else :data:`DEFAULT_MODEL`) and the names in the maps' tags for the
    classes without a given name; and a note for each choice."""
    notes, update = [], {}
    if models.model is None:
        strata = all(_is_strata(classes) for classes in class_maps)
        update["model"] = STRATA_MODEL if strata else DEFAULT_MODEL
        if strata:
            notes.append(f"model {STRATA_MODEL} for every class: the class map is NDVI strata (vegetation and soil, "
                         "brdfcorr classes ndvi); --model chooses another")
    tagged = tagged_class_names(*class_maps)
    given = {**(models.default_names or {}), **(models.names or {})}
    named = {key: value for key, value in tagged.items() if key not in given}
    if named:  # what the maps may hold: not checked against the classes found, as given names are
        update["default_names"] = {**(models.default_names or {}), **named}
        listed = ", ".join(f"{key}={value}" for key, value in sorted(named.items()))
        notes.append(f"class names from the class map's tags: {listed}")
    return replace(models, **update), notes


def _bbl_ranges(scene: SceneFiles, data: SceneData) -> tuple[list[list[float]], int]:
    """The wavelength ranges [nm] of the runs of bands (in wavelength order) that the ENVI header's
    ``bbl`` of ``scene`` marks bad, and their count; none for other files. Bands marked bad in an
    image without band wavelengths cannot be left out: an InputError says so."""
    bad = envi_bad_bands(scene.image) if isinstance(scene.image, (str, os.PathLike)) else None
    if bad is None or not bad.any():
        return [], 0
    if "wavelength" not in data.reflectance.coords:
        raise InputError(f"{scene.image_label}: the header's bbl marks {int(bad.sum())} bands bad but the image has no "
                         f"band wavelengths to leave them out by; give {option('wavelengths')}")
    centres = np.asarray(data.reflectance["wavelength"].values, dtype=float)
    order = np.argsort(centres, kind="stable")
    runs: list[list[float]] = []
    previous_bad = False
    for index in order:
        if bad[index] and previous_bad:
            runs[-1][1] = float(centres[index])
        elif bad[index]:
            runs.append([float(centres[index])] * 2)
        previous_bad = bool(bad[index])
    return runs, int(bad.sum())


def _bad_band_note(result: ClassFitResult, from_bbl: int) -> list[str]:
    """The summary line of the bands left out of the fit (none when none was)."""
    if not result.bands_left_out:
        return []
    ranges = ", ".join(f"{low:g}-{high:g}" if low != high else f"{low:g}" for low, high in result.bad_bands)
    source = f"; {from_bbl} marked bad by the ENVI header's bbl" if from_bbl else ""
    return [f"{len(result.bands_left_out)} bad bands left out of the fit ({ranges} nm{source}): no parameters in "
            "the table (bad_bands), brdfcorr correct passes them through uncorrected (QA flag band_uncorrected)"]


def _imagery_source(scenes: Sequence[SceneFiles], choice: ClassModels) -> str:
    """What an imagery fit used, for the table's ``fit:`` blocks: ``"brdfcorr fit-classes a.tif,
    b.tif (classes a_classes.tif, b_classes.tif; model torrance_sparrow)"``."""
    images = ", ".join(Path(scene.image_label).name for scene in scenes)
    classes = ", ".join(Path(scene.classes).name for scene in scenes)
    class_models = choice.class_models
    models = f"model {getattr(choice.model, 'name', choice.model)}" + (
        "; class models " + ", ".join(f"{key}={value}" for key, value in sorted(class_models.items()))
        if class_models else "")
    errors = ("; errors over the clusters of " + ", ".join(f"{Path(scene.clusters[0]).name} band {scene.clusters[1]}"
                                                          for scene in scenes if scene.clusters is not None)
              if any(scene.clusters is not None for scene in scenes) else "")
    return f"brdfcorr fit-classes {images} (classes {classes}; {models}{errors})"


def fit_class_files(
    scenes: Sequence[SceneFiles], models: ClassModels | str | None, *, sampling: Sampling = Sampling(),
    guard: GuardRails = GuardRails(), chunks: int | None = None, wavelengths: Sequence[float] | None = None,
    skip_unreadable: bool = False, progress=None, workers: int = 1,
) -> ImageryFitResult:
    """Fit per-class, per-band parameters from the pixels of one or many scenes.

    Each scene is opened lazily and checked (:func:`brdfcorr.io.scene.open_scene`), its stored
    values read as reflectance factors (the file's GDAL scale/offset, or the scene's ``scale`` and
    ``offset``), then the classes' pixels are pooled over the scenes, sampled and fitted
    (:func:`brdfcorr.fit.fit_classes`, with its guard rails). A scene without a given scale whose
    sample does not look like reflectance factors (raw counts) is an :class:`InputError`
    (:func:`brdfcorr.io.scale_check.check_reflectance_scale`).

    Parameters
    ----------
    scenes : sequence of SceneFiles
    models : ClassModels or str or None
        The classes, their names, models, fixed shape parameters and fallback materials, as for
        :func:`brdfcorr.fit.fit_classes` (a model name alone: ``ClassModels(model)``). Without a
        model (None, or ``ClassModels(None)``) the class maps choose it: ``ross_thick_li_sparse``
        where every map is NDVI strata (its ``strata`` tag, written by ``brdfcorr classes ndvi``),
        else ``torrance_sparrow``. Classes without a given name take the names of the maps'
        ``class_names`` tag. Both choices are listed in ``notes``.
    sampling : Sampling, default Sampling()
        As for :func:`brdfcorr.fit.fit_classes`, except ``reflectance_scale``: kept for callers
        of brdfcorr 0.1, it is the scale of every scene's stored values, applied on read as a given
        ``SceneFiles.scale`` (so it replaces a tagged scale, and the file's offset still applies);
        prefer ``SceneFiles.scale``. A scene with a different scale of its own is an
        :class:`InputError`.
    guard : GuardRails
        As for :func:`brdfcorr.fit.fit_classes`.
    chunks, wavelengths :
        As for :func:`brdfcorr.io.rasters.open_image`.
    skip_unreadable : bool, default False
        Leave out a scene that cannot be opened (listed in ``left_out``) instead of raising; at
        least one scene must open (a chain's fit step uses this).
    progress : callable, optional
        Called as ``progress(class_id)`` after each class is fitted (a progress bar's update).
    workers : int, default 1
        Processes that fit the classes side by side (:mod:`brdfcorr.tasks.pool`; the same fits as
        with one). Each starts by importing the fits (about a second): for many classes, or many
        samples per class.

    Notes
    -----
    Bad bands: the bands in ``sampling.bad_bands`` [nm] (default
    :data:`brdfcorr.fit.WATER_VAPOUR_BANDS`; ``()``: none) and those an ENVI image's header marks
    bad (``bbl``) are left out of the fit. The table's classes list them as ``bad_bands``
    (:func:`brdfcorr.fit.fit_classes`); ``notes`` says so.
    """
    if not isinstance(models, ClassModels):
        models = ClassModels(models)
    for scene in scenes:
        scene.check_flip(sampling.flip_view_azimuth)
    opened, used, left_out = _opened_scenes(scenes, sampling.reflectance_scale, chunks, wavelengths,
                                            skip_unreadable)
    models, notes = _choices_from_maps(models, [data.classes for data in opened])
    bbl = [_bbl_ranges(scene, data) for scene, data in zip(used, opened)]
    ranges = [*sampling.bad_bands, *(run for runs, _ in bbl for run in runs)]
    sampling = replace(sampling, reflectance_scale=1.0, bad_bands=tuple(map(tuple, ranges)))
    layers = _cluster_layers(used, opened, chunks)
    with process_pool(workers, ("brdfcorr.fit.classes",)) as executor:
        result, caught_notes = _fit_pooled(opened, models, sampling, guard, _imagery_source(used, models), progress,
                                           layers, executor)
    notes += _bad_band_note(result, max((count for _, count in bbl), default=0))
    return ImageryFitResult(result, used, _fitted_wavelengths(opened[0].reflectance, result), left_out, caught_notes,
                            notes)


def _cluster_layers(scenes: Sequence[SceneFiles], opened: Sequence[SceneData],
                    chunks: int | None) -> list[xr.DataArray] | None:
    """Each scene's cluster layer (:attr:`SceneFiles.clusters`), opened lazily and checked on its
    image's grid; None where no scene has one. Some scenes with a layer and others without is an
    :class:`InputError` (their errors would mix clusters and blocks)."""
    given = [scene.clusters is not None for scene in scenes]
    if not any(given):
        return None
    if not all(given):
        missing = ", ".join(scene.image_label for scene in scenes if scene.clusters is None)
        raise InputError(f"a cluster layer for {sum(given)} of {len(scenes)} images ({missing} has none): give one "
                         "per image, in the images' order")
    layers = []
    for scene, data in zip(scenes, opened):
        path, band = scene.clusters  # type: ignore[misc]  # all given (checked above)
        layers.append(rasters.open_clusters(path, chunks=chunks, band=band, like=data.reflectance,
                                            names=(scene.image_label, f"cluster layer {path}")))
    return layers


def _fit_pooled(opened: Sequence[SceneData], models: ClassModels, sampling: Sampling, guard: GuardRails, source: str,
                progress, clusters: list[xr.DataArray] | None = None,
                executor: concurrent.futures.Executor | None = None) -> tuple[ClassFitResult, list[str]]:
    """:func:`brdfcorr.fit.fit_classes` of the opened scenes' pixels (errors over the ``clusters``
    layers, if any; the classes fitted by ``executor``, if given), and its warnings
    (:class:`ClassFitWarning`) as notes."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ClassFitWarning)
        result = fit_classes([s.reflectance for s in opened], [s.classes for s in opened],
                             [xr.Dataset(s.angles) for s in opened], models, sampling=sampling, guard=guard,
                             progress=progress, clusters=clusters, executor=executor).with_source(source)
    return result, [str(w.message) for w in caught if issubclass(w.category, ClassFitWarning)]


def _fitted_wavelengths(reflectance: xr.DataArray, result: ClassFitResult) -> np.ndarray | None:
    """The band centres [nm] of the fitted bands (the bad bands left out), as the fits' arrays;
    None for an image without band wavelengths."""
    found = reflectance.coords["wavelength"].values if "wavelength" in reflectance.coords else None
    if found is not None and result.bad_bands:
        found = found[~in_ranges(found, result.bad_bands)]
    return found


def _opened_scenes(scenes: Sequence[SceneFiles], reflectance_scale: float, chunks, wavelengths,
                   skip_unreadable: bool) -> tuple[list[SceneData], list[SceneFiles], list[dict[str, str]]]:
    """Open and check each scene (:func:`fit_class_files`): the scenes' data, their files and the
    scenes left out (with ``skip_unreadable``)."""
    opened, used, left_out = [], [], []
    for scene in scenes:
        scale = scene.scale
        if reflectance_scale != 1.0:  # the 0.1 option: the scale of the stored values, now applied on read
            if scale is not None and scale != reflectance_scale:
                raise InputError(f"{scene.image_label}: scale {scale} and reflectance_scale {reflectance_scale} "
                                 "differ; give the scale once")
            scale = reflectance_scale
        try:
            sources = replace(scene, wavelengths=scene.wavelengths if wavelengths is None else wavelengths,
                              scale=scale)
            data = open_scene(sources, chunks=chunks,
                              prepare_classes=class_preparation(scene.align_classes, scene.class_lookup))
            if scale is None:
                scale_check.check_reflectance_scale(data.reflectance, scene.image_label)
        except BrdfcorrError as error:
            if not skip_unreadable:
                raise
            left_out.append({"scene": scene.name or scene.image_label, "reason": str(error)})
            continue
        opened.append(data)
        used.append(scene)
    if not opened:
        raise InputError("no scene could be opened for the imagery fit: "
                         + "; ".join(f"{s['scene']}: {s['reason']}" for s in left_out))
    return opened, used, left_out
