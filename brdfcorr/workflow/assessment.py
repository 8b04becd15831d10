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

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import xarray as xr

from brdfcorr import __version__
from brdfcorr.analysis.assess import (
    HeldOutLine,
    Line,
    assess_overlap,
    assess_view_angles,
    leave_one_line_out,
    leave_one_line_out_report,
    overlap_report,
    view_angle_report,
)
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import InputError
from brdfcorr.io import rasters
from brdfcorr.io.files import atomic_path
from brdfcorr.io.grid import check_same_grid
from brdfcorr.io.scene import SceneSources, open_scene
from brdfcorr.workflow.classmaps import class_preparation

__all__ = ["Assessment", "assess_files", "LinesAssessment", "leave_one_line_out_files", "write_json"]


@dataclass
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


def _open_scene_files(image, classes, angles, *, angles_kind: str, angle_options: dict | None, align_classes: bool,
                      class_lookup: Mapping[int, int] | None, scale: float | None, offset: float | None,
                      chunks: int | None, scheduler: str | None = None, num_workers: int | None = None):
    """One scene's files opened lazily and checked (:func:`brdfcorr.io.scene.open_scene`), the
    class map aligned or remapped as for the correction (:func:`brdfcorr.workflow.classmaps.class_preparation`)."""
    chunks = rasters.auto_chunk(image) if chunks is None else int(chunks)
    sources = SceneSources(image, classes, angles, angles_kind=angles_kind, angle_options=angle_options or {},
                           scale=scale, offset=offset)
    return open_scene(sources, chunks=chunks, prepare_classes=class_preparation(align_classes, class_lookup),
                      scheduler=scheduler, num_workers=num_workers)


def assess_files(
    before, after, *, classes, angles=None, angles_kind: str = "geotiff", angle_options: dict | None = None,
    overlap: tuple[str | os.PathLike, str | os.PathLike] | None = None, class_names: Mapping[int, str] | None = None,
    class_ids: Sequence[int] | None = None, by: Literal["sun", "track"] = "sun", heading: float | None = None,
    bin_width: float = 2.0, min_vza: float = 0.0, flip_view_azimuth: bool = False,
    align_classes: bool = False, class_lookup: Mapping[int, int] | None = None,
    scale: float | None = None, offset: float | None = None, chunks: int | None = None,
    resampling: str = "nearest", scheduler: str | None = None, num_workers: int | None = None,
) -> Assessment:
    """Assess a corrected image file against its input: view-angle signal per class and band, and
    optionally the difference in the overlap with another line.

    Parameters
    ----------
    before : path-like
        The input image (read as reflectance factors with its GDAL scale/offset, or ``scale`` and
        ``offset``), with its class map and angle source checked on its grid
        (:func:`brdfcorr.io.scene.open_scene`).
    after : path-like
        The corrected image, on the same grid (``brdfcorr correct``'s output: physical values).
    classes, angles, angles_kind, angle_options, align_classes, class_lookup, scale, offset, chunks :
        As for :func:`brdfcorr.workflow.correction.correct_files`.
    overlap : (path-like, path-like), optional
        Another line's input and corrected image (any grid; only the overlap is compared).
    class_names, class_ids, by, heading, bin_width, min_vza, flip_view_azimuth, scheduler, num_workers :
        As for :func:`assess_view_angles`.
    resampling : str, default "nearest"
        As for :func:`assess_overlap`.

    Returns
    -------
    Assessment
        ``report()`` is the JSON report; :func:`brdfcorr.plot.assess.write_assessment_figures`
        draws it.
    """
    chunks = rasters.auto_chunk(before) if chunks is None else int(chunks)
    scene = _open_scene_files(before, classes, angles, angles_kind=angles_kind, angle_options=angle_options,
                              align_classes=align_classes, class_lookup=class_lookup, scale=scale, offset=offset,
                              chunks=chunks, scheduler=scheduler, num_workers=num_workers)
    corrected = rasters.open_image(after, chunks=chunks)
    check_same_grid({"before": scene.reflectance, "after": corrected})
    if corrected.shape != scene.reflectance.shape:
        raise InputError(f"{after} has {corrected.shape[0]} bands, {before} has {scene.reflectance.shape[0]}")
    layers = scene.angles
    view = assess_view_angles(scene.reflectance, corrected, scene.classes, layers["vza"], layers["vaa"],
                              layers["saa"], by=by, heading=heading, class_ids=class_ids, class_names=class_names,
                              bin_width=bin_width, min_vza=min_vza, flip_view_azimuth=flip_view_azimuth,
                              scheduler=scheduler, num_workers=num_workers)
    inputs = {"before": str(before), "after": str(after), "classes": str(classes), "angles": str(angles)}
    result = Assessment(inputs, view)
    if overlap is not None:
        other_before = rasters.open_image(overlap[0], chunks=chunks, scale=scale, offset=offset)
        other_after = rasters.open_image(overlap[1], chunks=chunks)
        result.overlap = assess_overlap(scene.reflectance, corrected, other_before, other_after, resampling=resampling)
        inputs.update(overlap_before=str(overlap[0]), overlap_after=str(overlap[1]))
    return result


@dataclass
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


def leave_one_line_out_files(
    images: Sequence[str | os.PathLike], *, classes: Sequence[str | os.PathLike], angles: Sequence[str | os.PathLike],
    angles_kind: str = "geotiff", angle_options: dict | None = None, model: str = "torrance_sparrow",
    class_models: Mapping[int, str] | None = None, names: Mapping[int, str] | None = None,
    fixed: Mapping[str, float] | None = None, reference: Mapping[str, object] | None = None,
    limits: tuple[float, float] | None = DEFAULT_LIMITS, max_samples: int = 50_000, seed: int = 0,
    by: Literal["sun", "track"] = "sun", heading: float | None = None, bin_width: float = 2.0,
    overlap: bool = True, flip_view_azimuth: bool = False, align_classes: bool = False,
    class_lookup: Mapping[int, int] | None = None, scale: float | None = None, offset: float | None = None,
    chunks: int | None = None,
) -> LinesAssessment:
    """Leave-one-line-out on files: fit on N − 1 flight lines, correct the held-out one, assess
    it (:func:`leave_one_line_out`), for each of N lines.

    Parameters
    ----------
    images : sequence of path-like
        At least 2 reflectance images, one per flight line (read as reflectance factors [1] with
        their GDAL scale/offset, or ``scale`` and ``offset``), opened lazily and checked with their
        class maps and angle sources (:func:`brdfcorr.io.scene.open_scene`). Lines that overlap
        are compared in the overlap. A line's name in the report is its file's stem (its path where
        two stems are equal).
    classes, angles : sequence of path-like
        Class map and angle source of each image, in the images' order (``angles``: a 4-band
        raster of sza, saa, vza, vaa [deg], or what ``angles_kind`` names).
    angles_kind, angle_options, align_classes, class_lookup, scale, offset, chunks :
        As for :func:`assess_files`, the same for every line.
    model, class_models, names, fixed, reference, limits, max_samples, seed, by, heading, bin_width,
    overlap, flip_view_azimuth :
        As for :func:`leave_one_line_out`.

    Returns
    -------
    LinesAssessment
        The held-out lines' results; ``report()`` is the JSON report.
    """
    if not len(images) == len(classes) == len(angles):
        raise InputError(f"{len(images)} image(s), {len(classes)} class map(s) and {len(angles)} angle source(s): "
                         "give one class map and one angle source per image, in the same order")
    if len(images) < 2:
        raise InputError(f"leave-one-line-out needs at least 2 lines, got {len(images)}")
    line_names = _line_names(images)
    lines, inputs = [], []
    for name, image, class_map, angle_source in zip(line_names, images, classes, angles):
        scene = _open_scene_files(image, class_map, angle_source, angles_kind=angles_kind,
                                  angle_options=angle_options, align_classes=align_classes,
                                  class_lookup=class_lookup, scale=scale, offset=offset, chunks=chunks)
        lines.append(Line(name, scene.reflectance, scene.classes, scene.angles))
        inputs.append({"name": name, "image": str(image), "classes": str(class_map), "angles": str(angle_source)})
    results = leave_one_line_out(
        lines, model, class_models=class_models, names=names, fixed=fixed, reference=reference, limits=limits,
        max_samples=max_samples, seed=seed, by=by, heading=heading, bin_width=bin_width, overlap=overlap,
        flip_view_azimuth=flip_view_azimuth,
    )
    return LinesAssessment(inputs, results)
