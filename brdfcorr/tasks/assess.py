"""Assessing corrections on files: ``brdfcorr assess``, ``brdfcorr assess-lines`` and the chains'
assess step (the measures themselves: :mod:`brdfcorr.analysis.assess`).

- :func:`assess_files`: a corrected image against its input (view-angle signal per class and
  band; optionally the overlap with another line), an :class:`Assessment` whose ``report()`` is a
  JSON-serialisable dict;
- :func:`leave_one_line_out_files`: fit on N - 1 flight lines, correct and assess the held-out one,
  for each line (:class:`LinesAssessment`);
- :func:`write_json`: a report, written atomically.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import xarray as xr

from brdfcorr import __version__
from brdfcorr.analysis.assess import (
    HeldOutLine,
    HoldoutFit,
    Line,
    ViewAngleOptions,
    assess_overlap,
    assess_view_angles,
    leave_one_line_out,
    leave_one_line_out_report,
    overlap_report,
    view_angle_report,
)
from brdfcorr.errors import InputError
from brdfcorr.io import rasters
from brdfcorr.io.files import atomic_path
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.paths import same_file
from brdfcorr.io.scene import SceneData, SceneSources, open_scene
from brdfcorr.io.wavelengths import matched_bands
from brdfcorr.tasks.classmaps import class_preparation, tagged_class_names
from brdfcorr.tasks.request import Engine

__all__ = ["Assessment", "assess_files", "LinesAssessment", "check_line_files", "leave_one_line_out_files",
           "write_json"]


@dataclass(frozen=True)
class Assessment:
    """What :func:`assess_files` measured.

    Attributes
    ----------
    inputs : dict of str to str
        The files assessed, by role.
    view : xarray.Dataset
        :func:`assess_view_angles` of the scene.
    overlap : xarray.Dataset or None
        :func:`assess_overlap` with the other line, where one was given.
    """

    inputs: dict[str, str]
    view: xr.Dataset
    overlap: xr.Dataset | None = None

    def report(self) -> dict[str, object]:
        """A JSON-serialisable dict: ``brdfcorr_version``, ``inputs``, ``view_angles``
        (:func:`view_angle_report`) and ``overlap`` (:func:`overlap_report`, or None)."""
        return {
            "kind": "brdfcorr assess",
            "brdfcorr_version": __version__,
            "inputs": dict(self.inputs),
            "view_angles": view_angle_report(self.view),
            "overlap": None if self.overlap is None else overlap_report(self.overlap),
        }


def write_json(report: Mapping[str, object], target: str | os.PathLike) -> Path:
    """Write a report dict as indented JSON, atomically (:func:`brdfcorr.io.files.atomic_path`)."""
    target = Path(target)
    text = json.dumps(report, indent=2, allow_nan=False) + "\n"
    with atomic_path(target) as temporary:
        temporary.write_text(text, encoding="utf-8")
    return target


def _open_scene_files(sources: SceneSources, engine: Engine, *, align_classes: bool,
                      class_lookup: Mapping[int, int] | None) -> SceneData:
    """One scene's files opened lazily and checked (:func:`brdfcorr.io.scene.open_scene`) with the
    engine's chunks (default :func:`brdfcorr.io.rasters.auto_chunk`), scheduler and workers, the
    class map aligned or remapped as for the correction (:func:`brdfcorr.tasks.classmaps.class_preparation`)."""
    chunks = rasters.auto_chunk(sources.image) if engine.chunks is None else int(engine.chunks)
    return open_scene(sources, chunks=chunks, prepare_classes=class_preparation(align_classes, class_lookup),
                      scheduler=engine.scheduler, num_workers=engine.num_workers)


def _named(options: ViewAngleOptions, class_maps: Sequence[xr.DataArray]) -> ViewAngleOptions:
    """``options`` with the names in the class maps' tags (:func:`tagged_class_names`) for the
    classes it does not name."""
    tagged = tagged_class_names(*class_maps)
    return replace(options, class_names={**tagged, **(options.class_names or {})}) if tagged else options


@contextlib.contextmanager
def _active(callbacks: Sequence) -> Iterator[None]:
    """The engine's dask callbacks (a progress bar) active while the block computes."""
    with contextlib.ExitStack() as active:
        for callback in callbacks:
            active.enter_context(callback)
        yield


def assess_files(
    scene: SceneSources, after: str | os.PathLike, *, view_options: ViewAngleOptions = ViewAngleOptions(),
    overlap: tuple[str | os.PathLike, str | os.PathLike] | None = None, resampling: str = "nearest",
    clusters: tuple[str | os.PathLike, int] | None = None, align_classes: bool = False,
    class_lookup: Mapping[int, int] | None = None, engine: Engine = Engine(),
) -> Assessment:
    """Assess a corrected image file against its input: view-angle signal per class and band, and
    optionally the difference in the overlap with another line.

    Parameters
    ----------
    scene : SceneSources
        The input image (``before``: read as reflectance factors with its GDAL scale/offset, or the
        sources' ``scale`` and ``offset``), with its class map and angle source checked on its grid
        (:func:`brdfcorr.io.scene.open_scene`).
    after : path-like
        The corrected image, on the same grid (``brdfcorr correct``'s output: physical values).
    view_options : ViewAngleOptions
        How the view-angle signal is measured (:func:`assess_view_angles`): sign convention,
        classes and their names, bin width and smallest view zenith [deg], view azimuth convention.
    overlap : (path-like, path-like), optional
        Another line's input and corrected image (any grid; only the overlap is compared). The
        other input is read with the scene's ``scale`` and ``offset``.
    resampling : str, default "nearest"
        As for :func:`assess_overlap`.
    clusters : (path-like, int), optional
        A raster on the input's grid and its band (from 1) of integer ids of the units whose pixels
        share their errors (a composite's day-of-year band, a flight-line id): the slopes' 1-sigma
        is cluster-robust over these instead of square blocks (:func:`assess_view_angles`).
    align_classes, class_lookup :
        As for :class:`brdfcorr.tasks.request.CorrectionRequest`.
    engine : Engine
        Chunk size [pixels] (default :func:`brdfcorr.io.rasters.auto_chunk` of the input), dask
        scheduler and workers of the angle check and of the view-angle pass, and dask callbacks
        active meanwhile.

    Returns
    -------
    Assessment
        ``report()`` is the JSON report; :func:`brdfcorr.plot.assess.write_assessment_figures`
        draws it.
    """
    scene.check_flip(view_options.flip_view_azimuth)
    engine = replace(engine, chunks=rasters.auto_chunk(scene.image) if engine.chunks is None else int(engine.chunks))
    # GDAL's block cache bounded for every pass (issue 28; GDAL's default keeps every tile read).
    with _active(engine.callbacks), rasters.bounded_gdal_cache(scene.image, engine.chunks):
        data = _open_scene_files(scene, engine, align_classes=align_classes, class_lookup=class_lookup)
        view_options = _named(view_options, [data.classes])
        corrected = _corrected_on_grid(after, scene.image, data.reflectance, engine.chunks)
        other = None if overlap is None else _other_line(overlap, scene, data.reflectance, engine.chunks)
        layers = data.angles
        cluster_layer = None if clusters is None else _cluster_layer(clusters, data.reflectance, engine.chunks)
        view = assess_view_angles(data.reflectance, corrected, data.classes, layers["vza"], layers["vaa"],
                                  layers["saa"], clusters=cluster_layer, options=view_options,
                                  scheduler=engine.scheduler, num_workers=engine.num_workers)
        if int(view["pixels"].sum()) == 0:  # an all-NaN AFTER (or BEFORE, or no class): an empty report
            raise InputError(f"no pixel of a class is valid (finite) in every band of both {scene.image} and {after}: "
                             "nothing to assess (is one of them all nodata?)")
        overlapped = None if other is None else assess_overlap(data.reflectance, corrected, *other,
                                                               resampling=resampling)
    return Assessment(_assessed_inputs(scene, after, clusters, overlap), view, overlapped)


def _corrected_on_grid(after, image, before: xr.DataArray, chunks: int) -> xr.DataArray:
    """The corrected image, opened and checked against its input: the same grid, the same bands."""
    corrected = rasters.open_image(after, chunks=chunks)
    check_same_grid({"before": before, "after": corrected})
    return matched_bands(corrected, before, (str(after), str(image)))


def _other_line(overlap, scene: SceneSources, before: xr.DataArray, chunks: int) -> tuple[xr.DataArray, xr.DataArray]:
    """Another line's input (read with the scene's scale and offset) and corrected image, checked
    to be another file than the scene's and to hold its bands before any pass
    (:func:`assess_overlap` compares them band by band; a line compared with itself agrees to 0)."""
    if same_file(overlap[0], scene.image):
        raise InputError(f"--overlap {overlap[0]} is the assessed image itself: give another line's input and "
                         "corrected image, which overlap this one")
    other = (rasters.open_image(overlap[0], chunks=chunks, scale=scene.scale, offset=scene.offset),
             rasters.open_image(overlap[1], chunks=chunks))
    why = ": the overlap compares a line with another of the same bands"
    return tuple(matched_bands(image, before, (str(path), str(scene.image)), why)  # type: ignore[return-value]
                 for path, image in zip(overlap, other))


def _cluster_layer(clusters: tuple[str | os.PathLike, int], image: xr.DataArray, chunks: int) -> xr.DataArray:
    """Band ``clusters[1]`` of the cluster raster ``clusters[0]``, checked on the image's grid."""
    return rasters.open_clusters(clusters[0], chunks=chunks, band=clusters[1], like=image)


def _assessed_inputs(scene: SceneSources, after, clusters, overlap) -> dict[str, str]:
    """The files an assessment read, by role (the report's ``inputs``)."""
    inputs = {"before": str(scene.image), "after": str(after), "classes": str(scene.classes),
              "angles": str(scene.angles)}
    inputs.update({name: str(path) for name in ("sza", "saa", "vza", "vaa")
                   if (path := getattr(scene, name)) is not None})
    if clusters is not None:
        inputs["clusters"] = f"{clusters[0]} band {clusters[1]}"
    if overlap is not None:
        inputs.update(overlap_before=str(overlap[0]), overlap_after=str(overlap[1]))
    return inputs


@dataclass(frozen=True)
class LinesAssessment:
    """What :func:`leave_one_line_out_files` measured.

    Attributes
    ----------
    inputs : list of dict of str to str
        Per line, in order: its ``name`` and its ``image``, ``classes`` and ``angles`` files.
    lines : list of HeldOutLine
        :func:`leave_one_line_out` of the lines, one per held-out line.
    """

    inputs: list[dict[str, str]]
    lines: list[HeldOutLine]

    def report(self) -> dict[str, object]:
        """A JSON-serialisable dict: ``kind``, ``brdfcorr_version``, ``inputs`` and, per held-out
        line, what :func:`leave_one_line_out_report` gives (``lines``)."""
        report = leave_one_line_out_report(self.lines)
        return {"kind": report["kind"], "brdfcorr_version": __version__,
                "inputs": [dict(entry) for entry in self.inputs], "lines": report["lines"]}


def _line_names(images: Sequence[str | os.PathLike]) -> list[str]:
    """Names of the lines in reports: the files' stems, or their paths where two stems are equal."""
    if len({str(Path(image).resolve()) for image in images}) < len(images):
        raise InputError(f"an image is given twice among {', '.join(map(str, images))}: give each line once")
    stems = [Path(image).stem for image in images]
    return stems if len(set(stems)) == len(stems) else [str(image) for image in images]


def check_line_files(images: Sequence, classes: Sequence, angles: Sequence) -> None:
    """One class map and one angle source per image (``brdfcorr assess-lines``), else an
    :class:`~brdfcorr.errors.InputError` that counts them."""
    if not len(images) == len(classes) == len(angles):
        raise InputError(f"{len(images)} image(s), {len(classes)} class map(s) and {len(angles)} angle source(s): "
                         "give one class map and one angle source per image, in the same order")


def leave_one_line_out_files(
    scenes: Sequence[SceneSources], fit: HoldoutFit = HoldoutFit(), *,
    view_options: ViewAngleOptions = ViewAngleOptions(), overlap: bool = True, align_classes: bool = False,
    class_lookup: Mapping[int, int] | None = None, chunks: int | None = None,
    clusters: Sequence[tuple[str | os.PathLike, int]] | None = None,
) -> LinesAssessment:
    """Leave-one-line-out on files: fit on N − 1 flight lines, correct the held-out one, assess
    it (:func:`leave_one_line_out`), for each of N lines.

    Parameters
    ----------
    scenes : sequence of SceneSources
        At least 2 flight lines: each one's reflectance image (read as reflectance factors [1] with
        its GDAL scale/offset, or the sources' ``scale`` and ``offset``), class map and angle
        source (a 4-band raster of sza, saa, vza, vaa [deg], or what ``angles_kind`` names),
        opened lazily and checked (:func:`brdfcorr.io.scene.open_scene`). Lines that overlap are
        compared in the overlap. A line's name in the report is its image's stem (its path where
        two stems are equal).
    fit, view_options, overlap :
        As for :func:`leave_one_line_out`. The class maps' ``class_names`` tags
        (:func:`~brdfcorr.tasks.classmaps.tagged_class_names`) name the classes that
        ``view_options.class_names`` does not, as ``fit.default_names``: a tagged class that a
        fold's training lines do not hold is not warned about, a given name of one is.
    align_classes, class_lookup :
        As for :func:`assess_files`, the same for every line.
    chunks : int, optional
        Chunk size [pixels] of every line (default :func:`brdfcorr.io.rasters.auto_chunk` of each
        image).
    clusters : sequence of (path-like, int), optional
        Per line, in order, a cluster layer on its grid and its band (as for :func:`assess_files`).

    Returns
    -------
    LinesAssessment
        The held-out lines' results; ``report()`` is the JSON report.
    """
    if len(scenes) < 2:
        raise InputError(f"leave-one-line-out needs at least 2 lines, got {len(scenes)}")
    for scene in scenes:
        scene.check_flip(view_options.flip_view_azimuth)
    line_names = _line_names([scene.image for scene in scenes])
    if clusters is not None and len(clusters) != len(scenes):
        raise InputError(f"{len(scenes)} line(s) and {len(clusters)} cluster layer(s): give one per line, in order")
    lines, inputs = [], []
    for index, (name, scene) in enumerate(zip(line_names, scenes)):
        data = _open_scene_files(scene, Engine(chunks=chunks), align_classes=align_classes,
                                 class_lookup=class_lookup)
        entry = {"name": name, "image": str(scene.image), "classes": str(scene.classes), "angles": str(scene.angles)}
        layer = None
        if clusters is not None:
            path, band = clusters[index]
            size = rasters.auto_chunk(scene.image) if chunks is None else int(chunks)
            layer = rasters.open_clusters(path, chunks=size, band=band, like=data.reflectance)
            entry["clusters"] = f"{path} band {band}"
        lines.append(Line(name, data.reflectance, data.classes, data.angles, layer))
        inputs.append(entry)
    # The names in the maps' tags describe what a map may hold: a class none of a fold's training
    # lines holds is not worth a warning, as a name the user gave is (HoldoutFit.default_names).
    tagged = tagged_class_names(*(line.classes for line in lines))
    if tagged:
        fit = replace(fit, default_names={**tagged, **(fit.default_names or {})})
    results = leave_one_line_out(lines, fit, view_options=view_options, overlap=overlap)
    return LinesAssessment(inputs, results)
