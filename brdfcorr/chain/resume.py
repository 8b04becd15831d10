"""What a resumed chain run may skip: the parameter table known before the run, the fingerprint a
corrected output records of its inputs and settings, and the checks that turn a skipped scene
back to ``run`` (:func:`redo_stale`).

A scene whose complete outputs exist is skipped (``outputs.existing: skip``) only when they are still
whole (:func:`brdfcorr.io.commit.check_complete`, as a fresh write is checked) and its corrected image
records (provenance tag ``brdf_parameter_table_content``) the parameter table this run will use
(:func:`planned_table`) and the fingerprint this run would write (:func:`scene_fingerprint`; tags
``brdf_fingerprint``, ``brdf_fingerprint_content``); the reason it is redone names what changed.
A scene the earlier run failed (its run report, :func:`earlier_report`) is redone whatever its
outputs: a scene fails after its outputs are written where too few of its pixels were corrected.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import stat
import warnings
from pathlib import Path

import rasterio
import rasterio.errors

from brdfcorr import __version__
from brdfcorr.chain.config import ChainConfig
from brdfcorr.chain.scenes import Scene
from brdfcorr.errors import InputError, ParameterError
from brdfcorr.io.commit import check_complete
from brdfcorr.io.files import content_digest
from brdfcorr.params import ClassEntry, ParameterTable, merge_tables

__all__ = ["configured_table", "with_strata_interpolation", "reuses_fit", "planned_table", "redo_stale",
           "scene_fingerprint", "fit_fingerprint", "earlier_report", "reused_fit_report"]


# ------------------------------------------------------------------------------------ parameters
def configured_table(config: ChainConfig) -> ParameterTable:
    """The parameters given in the config: built-in materials, inline classes, the table file
    (later wins for a class id)."""
    entries = []
    for class_id, name in sorted(config.parameters.materials.items()):
        entries.append(ClassEntry(id=class_id, material=name))  # the library's model and values
    tables = [ParameterTable(classes=entries), ParameterTable(classes=list(config.parameters.classes)),
              config.given_table()]
    return merge_tables(table for table in tables if table is not None)


def with_strata_interpolation(table: ParameterTable, config: ChainConfig) -> ParameterTable:
    """``table`` with the ``ndvi_interpolation:`` block of ``steps.strata.ndvi_interpolation`` over
    the strata it holds, in increasing NDVI (a stratum the fit left out is not in it); ``table``
    itself without that key.

    Raises
    ------
    InputError
        Fewer than two strata in the table, or strata whose models cannot be interpolated
        (:meth:`brdfcorr.params.NdviInterpolation.check_classes`).
    """
    step = config.steps.strata
    if step is None or not step.ndvi_interpolation:
        return table
    strata = [class_id for class_id in step.strata_ids() if class_id in table]
    key = "steps.strata.ndvi_interpolation"
    if len(strata) < 2:
        raise InputError(f"{key}: it needs two strata in the parameter table, which has "
                         f"{len(strata)} of the strata {', '.join(map(str, step.strata_ids()))}")
    try:
        return table.with_ndvi_interpolation({"classes": strata})
    except ParameterError as error:
        raise InputError(f"{key}: {error}") from None


def reuses_fit(config: ChainConfig, fit_output: Path | None, report: Path, fingerprint: str | None) -> bool:
    """Whether the run reuses the fitted table of an earlier run (resume) instead of fitting: with
    ``outputs.existing: skip``, where the table exists and the earlier run's report (at ``report``)
    records the fit ``fingerprint`` of this run (:func:`fit_fingerprint`: the same fit settings
    and inputs)."""
    if fit_output is None or config.outputs.existing != "skip" or not fit_output.exists():
        return False
    fit = earlier_report(report).get("fit")
    return isinstance(fit, dict) and fit.get("fingerprint") == fingerprint


def fit_fingerprint(config: ChainConfig, scenes: list[Scene]) -> str | None:
    """What a chain's fitted table depends on, as the SHA-256 of canonical JSON: the fit step's
    settings, the brdfcorr version and its inputs (each measurement file, or each scene's image,
    class map and angle files, as :func:`scene_fingerprint` records them, with the ``inputs`` and
    ``steps.strata`` settings, and ``flip_view_azimuth`` where the view azimuths are flipped,
    :attr:`ChainConfig.flips_view_azimuth`); None without a fit step."""
    step = config.steps.fit
    if step is None:
        return None
    document: dict = {"brdfcorr": __version__, "fit": step.model_dump(mode="json", exclude={"output"})}
    if step.source == "goniometer":
        document["inputs"] = [_file_state(config.resolve(item.file)) for item in step.measurements]
    else:
        document["inputs"] = [{role: _file_state(path) for role, path in scene.inputs()} for scene in scenes]
        # flip_view_azimuth below, once: where set as the correct step's key or at inputs alike
        document["settings"] = config.inputs.model_dump(mode="json",
                                                        exclude={"images", "scene_regex", "flip_view_azimuth"})
        if config.steps.strata is not None:
            document["strata"] = config.steps.strata.model_dump(mode="json")
        if config.flips_view_azimuth:  # the fit reads the view azimuths as the correction does
            document["flip_view_azimuth"] = True
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def earlier_report(report: Path) -> dict:
    """The run report an earlier run left at ``report`` (empty where there is none or it is unreadable)."""
    try:
        found = json.loads(report.read_text())
    except (OSError, ValueError):
        return {}
    return found if isinstance(found, dict) else {}


def reused_fit_report(step_source: str, fit_output: Path, report: Path) -> dict:
    """The fit report of a run that reuses the fitted table at ``fit_output`` (:func:`reuses_fit`):
    the earlier run's fingerprint and the classes its fit reported (those its guard rails left
    uncorrected still fail the scenes that hold them)."""
    fit = earlier_report(report)["fit"]
    return {"source": step_source, "reused": str(fit_output), "fingerprint": fit["fingerprint"],
            **({"classes": fit["classes"]} if fit.get("classes") else {})}


def planned_table(config: ChainConfig, reused: Path | None) -> ParameterTable | None:
    """The parameter table the run will use, as known before it runs: the configured table and the
    fitted table it reuses (``reused``, :func:`reuses_fit`); None when the fit step makes a new table."""
    if config.steps.fit is None:
        return with_strata_interpolation(configured_table(config), config)
    if reused is None:
        return None
    return with_strata_interpolation(merge_tables([configured_table(config), ParameterTable.load(reused)]), config)


# ----------------------------------------------------------------------------------------- resume
def redo_stale(config: ChainConfig, scenes: list[Scene], reused: Path | None, report: Path) -> list[Scene]:
    """The scenes, with skipped ones turned to ``run`` when the earlier run (its report at
    ``report``) failed them, does not vouch for their corrected outputs (:func:`_unvouched`), or
    their outputs were not made with the run's parameter table (with the fitted table it
    ``reused``, if any), inputs and settings."""
    results = earlier_report(report).get("scenes")
    results = [result for result in results if isinstance(result, dict)] if isinstance(results, list) else []
    failed = {str(result.get("image")) for result in results if result.get("status") == "failed"}
    vouched = {str(result.get("image")): result for result in results if result.get("status") in ("ok", "skipped")}
    scenes = [dataclasses.replace(scene, action="run", reason="failed in the earlier run: redone")
              if scene.action == "skip" and str(scene.image) in failed else scene for scene in scenes]
    if not any(scene.action == "skip" and "corrected" in scene.outputs for scene in scenes):
        return scenes
    table_file = config.table_path()
    if table_file is not None and not table_file.exists():
        return scenes  # without require_inputs only: the run stops before any scene (a plan warning)
    table = planned_table(config, reused)
    return [_unvouched(_unless_stale(scene, table), vouched.get(str(scene.image))) for scene in scenes]


def fingerprint_digest(scene: Scene) -> str:
    """The SHA-256 of the scene's fingerprint: its outputs' tag ``brdf_fingerprint``, and the
    report's record of the run that wrote them."""
    return hashlib.sha256(scene.fingerprint.encode()).hexdigest()


def _unvouched(scene: Scene, earlier: dict | None) -> Scene:
    """The skipped scene turned to ``run`` unless the earlier report (``earlier``: its result for
    the scene) says that its run wrote every output this run asks for with this fingerprint: the
    QA counts a skipped scene reports, and judges the scene by, are that run's. Without it, a
    scene that failed (its uncorrected output kept) passed when the report was gone, a QA raster of
    other limits was kept beside a corrected image of new ones, and a run killed after rewriting
    some scenes left their counts of the run before."""
    if scene.action != "skip" or "corrected" not in scene.outputs:
        return scene
    if earlier is None:
        reason = "no earlier run report vouches for its outputs"
    elif earlier.get("fingerprint") != fingerprint_digest(scene):
        reason = "its outputs are not those the earlier run report describes"
    else:
        missing = sorted(set(scene.outputs) - set(earlier.get("outputs") or {}))
        if not missing:
            return scene
        reason = f"the earlier run did not write its {', '.join(missing)} output"
    return dataclasses.replace(scene, action="run", reason=f"{reason}: redone")


def _unless_stale(scene: Scene, table: ParameterTable | None) -> Scene:
    """The scene, turned from ``skip`` to ``run`` if its corrected output was written with another
    parameter table than ``table`` (provenance tag ``brdf_parameter_table_content`` of
    :func:`brdfcorr.tasks.correct.correct_files`) or ``table`` is not known before the run, or
    with another fingerprint than ``scene.fingerprint`` (tag ``brdf_fingerprint``)."""
    if scene.action != "skip" or "corrected" not in scene.outputs:
        return scene
    damaged = _damaged(scene)
    if damaged:
        return dataclasses.replace(scene, action="run", reason=f"{damaged}: redone")
    if table is None:
        return dataclasses.replace(scene, action="run", reason="the fit step makes a new parameter table")
    try:
        with rasterio.open(scene.outputs["corrected"]) as dataset:
            tags = dataset.tags()
        written = json.loads(tags.get("brdf_parameter_table_content", "null"))
    except (rasterio.errors.RasterioError, ValueError):
        tags, written = {}, None
    if written != json.loads(json.dumps(table.to_dict())):
        return dataclasses.replace(scene, action="run", reason="outputs were made with another parameter table")
    if tags.get("brdf_fingerprint") != fingerprint_digest(scene):
        return dataclasses.replace(scene, action="run", reason=_what_changed(tags, scene.fingerprint))
    return scene


#: The outputs of a scene that are rasters (checked as a fresh write is before a resume skips them).
_RASTERS = ("corrected", "qa", "uncertainty", "strata")


def _damaged(scene: Scene) -> str | None:
    """The first of a skipped scene's outputs that is no longer whole, in words: a raster cut short
    or unreadable (:func:`brdfcorr.io.commit.check_complete`, as a fresh write is checked), an
    assessment that is no JSON. None when all are whole."""
    for role, path in scene.outputs.items():
        if role in _RASTERS:
            problem = check_complete(path)
        elif path.suffix == ".json":
            problem = _json_problem(path)
        else:
            continue
        if problem is not None:
            return f"{role} output {path} is damaged ({problem})"
    return None


def _json_problem(path: Path) -> str | None:
    try:
        json.loads(path.read_bytes())
    except (OSError, ValueError) as error:
        return f"it is no JSON document: {error}"
    return None


# ----------------------------------------------------------------------------------- fingerprints
def scene_fingerprint(scene: Scene, config: ChainConfig) -> str:
    """Everything a scene's corrected output depends on besides the parameter table, as canonical
    JSON (sorted keys, no spaces): what :func:`brdfcorr.tasks.correct.correct_files` records
    (tags ``brdf_fingerprint``, its SHA-256, and ``brdf_fingerprint_content``) and a resumed run
    compares.

    It holds the input files' (image, class map, angles, terrain source; a product's bands, mask
    and angle metadata) path (as given), size,
    modification time [ns] and content digest (:func:`brdfcorr.io.files.content_digest`; the
    acquisition time of a ``solar`` angle source), the angle source's
    kind and options, the other ``inputs`` settings (wavelengths, class lookup, ...), the reference
    geometry, the correct step's options (limits, terrain, ...; not ``qa``: the QA and uncertainty
    rasters are extra outputs of the same pass, their presence is checked as a file's), the output
    format (compression, COG, ENVI interleave), the ``steps.strata`` settings where that step derives
    the class map (then no input), the ``steps.assess`` and ``steps.quicklook`` settings where the
    scene has those outputs (a changed setting redoes the scene, its correction too) and the
    brdfcorr version. The parameter table is recorded in
    full apart from it (tag ``brdf_parameter_table_content``, :func:`planned_table`): a table from
    the fit step is only known once the run has fitted it.
    """
    inputs = {role: _file_state(path) for role, path in scene.inputs()}
    if scene.angles_kind == "solar":
        inputs["angles"] = {"time": scene.angles}
    # Not qa and min_corrected_share: an extra output, and a check of the counts after the write.
    correct = None if config.steps.correct is None else config.steps.correct.model_dump(
        mode="json", exclude={"qa", "min_corrected_share"})
    if correct is not None:  # the defaults of later options are not recorded: older outputs stay current
        if correct["terrain"] is None:  # a flat correction records what it did before terrain
            del correct["terrain"]
        if correct["factor_at"] == "pixels":
            del correct["factor_at"]
    document = {
        "brdfcorr": __version__,
        "inputs": inputs,
        "angle source": {"kind": scene.angles_kind, "options": scene.angle_options},
        # flip_view_azimuth: the correct step's, which inputs.flip_view_azimuth sets (ChainConfig)
        "settings": config.inputs.model_dump(mode="json", exclude={"images", "scene_regex", "angles", "classes",
                                                                    "slope_aspect", "dem", "flip_view_azimuth"}),
        "reference": None if config.reference is None else config.reference.model_dump(mode="json"),
        "correct": correct,
        "format": config.outputs.model_dump(mode="json", include={"format", "compress", "cog", "interleave"},
                                            exclude_none=True),
    }
    if config.steps.strata is not None:  # the derived class map's settings (its file is an output)
        document["strata"] = config.steps.strata.model_dump(mode="json")
    for name in ("assess", "quicklook"):  # outputs of the scene too: redone with the scene
        step = getattr(config.steps, name)
        if step is not None:
            document[name] = step.model_dump(mode="json")
    return json.dumps(document, sort_keys=True, separators=(",", ":"), default=str)


def _file_state(path: Path) -> dict:
    """A file's identity in a fingerprint: path (as given), size [bytes], modification time [ns] and
    content (:func:`brdfcorr.io.files.content_digest`: an edit in place that kept the size and the
    time changes it), and those of the files GDAL reads with a raster (``sidecars`` by name, where
    it has any: an ``.aux.xml`` with the bands' scale, nodata or wavelengths, an ENVI ``.hdr``).
    Only regular files are read (a FIFO would block); a product folder is its path only (its files
    are inputs of their own: a file added beside them changes nothing)."""
    try:
        status = os.stat(path)
        if stat.S_ISDIR(status.st_mode):
            return {"path": str(path)}
        digest = content_digest(path) if stat.S_ISREG(status.st_mode) else None
    except OSError:
        return {"path": str(path)}
    state = {"path": str(path), "size": status.st_size, "mtime_ns": status.st_mtime_ns, "content": digest}
    sidecars = {Path(name).name: _file_state(Path(name)) for name in _sidecars(path)} if digest else {}
    return {**state, "sidecars": sidecars} if sidecars else state


def _sidecars(path: Path) -> list[str]:
    """The files other than ``path`` that GDAL reads with the raster at ``path`` (none for a file
    that is no raster: a measurement table)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # NotGeoreferencedWarning and the like: no matter for a file list
        try:
            with rasterio.open(path) as dataset:
                files = dataset.files
        except Exception:  # noqa: BLE001 (no raster GDAL can open: no sidecar)
            return []
    return sorted(name for name in files if os.path.abspath(name) != os.path.abspath(path))


#: How a reason names a part of a fingerprint.
_PARTS = {"brdfcorr": "brdfcorr version", "angle source": "angle source", "settings": "inputs settings",
          "reference": "reference geometry", "correct": "steps.correct", "format": "output format",
          "strata": "steps.strata", "assess": "steps.assess", "quicklook": "steps.quicklook"}


def _what_changed(tags: dict, fingerprint: str) -> str:
    """Why an output's recorded fingerprint is not ``fingerprint``, in words ("reference geometry
    changed since it was written")."""
    generic = "inputs or settings changed since it was written"
    try:
        written, planned = json.loads(tags["brdf_fingerprint_content"]), json.loads(fingerprint)
    except (KeyError, ValueError):  # an output of a brdfcorr that recorded no fingerprint
        return generic
    if not isinstance(written, dict):
        return generic
    changed = []
    for part, value in planned.items():
        if written.get(part) == value:
            continue
        if part == "inputs":
            old = written.get(part) if isinstance(written.get(part), dict) else {}
            changed += [f"{role} {value[role].get('path', value[role].get('time'))}" for role in value
                        if old.get(role) != value[role]]
        elif part == "correct" and isinstance(written.get(part), dict) and isinstance(value, dict):
            changed += [f"steps.correct.{key}" for key in value if written[part].get(key) != value[key]]
        else:
            changed.append(_PARTS.get(part, part))
    return f"{', '.join(changed)} changed since it was written" if changed else generic
