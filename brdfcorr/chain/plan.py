"""What a chain run will do: its scenes, their files, and what happens to each (:func:`plan_run`).

A plan expands a :class:`~brdfcorr.chain.config.ChainConfig` into scenes (image, angle source,
class map and output names for every input image) and decides each scene's action:

``run``   the scene is corrected;
``skip``  its complete outputs exist (``outputs.existing: skip``) and were made from the same inputs,
          settings and parameter table as this run would use;
``fail``  an input is missing, or its outputs exist under ``outputs.existing: error``.

The plan is the one place that decides: ``brdfcorr run --dry-run`` shows it and
:func:`brdfcorr.chain.run.run_chain` follows it, so both say the same about every scene.
Outputs appear complete or not at all, and a skipped scene's outputs are reopened and checked as a
fresh write is (:func:`brdfcorr.io.commit.check_complete`: one cut short after the run is redone); it is still
redone when its corrected image records (provenance tag ``brdf_parameter_table_content``) another
parameter table than the one this run will use (:func:`planned_table`), or another fingerprint
(tags ``brdf_fingerprint``, ``brdf_fingerprint_content``) than the one this run would write
(:func:`scene_fingerprint`: the input files' path, size, modification time and content digest, the reference
geometry, limits and other settings, the brdfcorr version). When the fit step makes a new table,
that table is not known before the run, and such scenes are redone.

Before anything runs, every file the run writes (scene outputs, run report, fitted table) is
checked against every file it reads (every scene's inputs, the chain config, the parameter table,
measurement files) and against each other (:func:`brdfcorr.io.paths.check_outputs`). Paths keep
the form the config gives them (a scene image given as a link has ``{dir}`` of the link); file
identity is only compared in that check.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import json
import os
import re
import stat
from dataclasses import dataclass
from pathlib import Path

import rasterio
import rasterio.errors

from brdfcorr import __version__
from brdfcorr.chain.config import ChainConfig, format_pattern
from brdfcorr.errors import InputError, OutputError
from brdfcorr.fit.settings import DEFAULT_MODEL, STRATA_MODEL
from brdfcorr.io.commit import check_complete
from brdfcorr.io.files import content_digest
from brdfcorr.io.paths import InputOverwriteError, check_outputs
from brdfcorr.io.writer import envi_sidecars
from brdfcorr.params import ClassEntry, ParameterTable, merge_tables
from brdfcorr.plot.assess import figure_paths

__all__ = ["Scene", "RunPlan", "plan_run", "configured_table", "reuses_fit", "planned_table", "scene_fingerprint"]


@dataclass(frozen=True)
class Scene:
    """One input image and everything the chain reads and writes for it.

    Attributes
    ----------
    name : str
        Scene name (``{scene}`` in patterns).
    image, classes : Path
        Reflectance image and class map.
    angles_kind : str
        Angle source kind (``geotiff``, ``envi_obs``, ...).
    angles : str
        The angle source: a path, or for ``solar`` the acquisition time.
    angle_options : dict
        Options of the angle reader.
    outputs : dict of str to Path
        ``corrected`` and, when enabled, ``qa``, ``uncertainty``, ``assess`` (JSON report),
        ``assess_profiles`` (its figure) and ``quicklook``.
    action : {"run", "skip", "fail"}
        What the run will do; ``reason`` says why for ``skip`` and ``fail`` (and for ``run`` when
        existing outputs are redone).
    fingerprint : str
        What the corrected output will record of its inputs and settings
        (:func:`scene_fingerprint`).
    slope_aspect, dem : Path, optional
        The terrain source of ``steps.correct.terrain`` (one of them, or neither).
    """

    name: str
    image: Path
    classes: Path
    angles_kind: str
    angles: str
    angle_options: dict
    outputs: dict
    action: str = "run"
    reason: str = ""
    fingerprint: str = ""
    slope_aspect: Path | None = None
    dem: Path | None = None

    def inputs(self) -> list[tuple[str, Path]]:
        """(role, path) of the files the scene reads: image, class map, angle file and the terrain
        source."""
        files = [("image", self.image)]
        if self.classes != Path():  # Path(): a scene failed before its files were named
            files.append(("class map", self.classes))
        if self.angles_kind != "solar" and self.angles:  # the solar source is a time, not a file
            files.append(("angles", Path(self.angles)))
        files += [(role, path) for role, path in (("slope/aspect", self.slope_aspect), ("DEM", self.dem))
                  if path is not None]
        return files

    def describe(self) -> dict:
        """JSON-friendly description (for the report and ``--dry-run``)."""
        return {
            "scene": self.name,
            "image": str(self.image),
            "angles": {"kind": self.angles_kind, "source": self.angles, **(
                {"options": self.angle_options} if self.angle_options else {})},
            "classes": str(self.classes),
            **{role: str(path) for role, path in (("slope_aspect", self.slope_aspect), ("dem", self.dem))
               if path is not None},
            "outputs": {key: str(value) for key, value in self.outputs.items()},
            "action": self.action,
            **({"reason": self.reason} if self.reason else {}),
        }


@dataclass(frozen=True)
class RunPlan:
    """What a chain run will do: its scenes, files and steps (:func:`plan_run`)."""

    config: ChainConfig
    scenes: tuple[Scene, ...]
    output_dir: Path
    report: Path
    fit_output: Path | None
    table_sources: tuple[str, ...]
    warnings: tuple[str, ...] = ()
    #: The warnings that name an input the run needs and cannot find (planned with
    #: ``require_inputs=False``): an image pattern, the parameter table, a measurement file. Scenes
    #: with a missing class map or angle file are those whose action is ``fail`` (:meth:`missing_inputs`).
    missing: tuple[str, ...] = ()

    def missing_inputs(self) -> list[str]:
        """Every input the run would miss, in words: :attr:`missing`, then each scene failing for a
        missing input (``scene NAME: missing input: ...``). Empty when the chain can run."""
        scenes = [f"scene {scene.name}: {scene.reason}" for scene in self.scenes
                  if scene.action == "fail" and scene.reason.startswith("missing input")]
        return [*self.missing, *scenes]

    @property
    def steps(self) -> list[str]:
        steps = self.config.steps
        return [name for name in ("fit", "correct", "assess", "quicklook") if getattr(steps, name) is not None]

    def files_written(self) -> list[Path]:
        """Every file the run may write: the scenes' outputs, the run report, the fitted table."""
        files = [path for scene in self.scenes for path in scene.outputs.values()] + [self.report]
        return files + ([self.fit_output] if self.fit_output is not None else [])

    def describe(self) -> dict:
        """JSON-friendly summary: steps, parameter sources, engine, scenes and their actions."""
        engine = self.config.engine
        return {
            "config": self.config.source,
            "steps": self.steps,
            "parameters": list(self.table_sources),
            "reference": None if self.config.reference is None else self.config.reference.model_dump(),
            "engine": engine.model_dump(),
            "output_directory": str(self.output_dir),
            "report": str(self.report),
            "scenes": [scene.describe() for scene in self.scenes],
            "warnings": list(self.warnings),
        }


def plan_run(config: ChainConfig, *, require_inputs: bool = True) -> RunPlan:
    """Expand a config into scenes and decide what happens to each; checks the parameter sources.

    Parameters
    ----------
    config : ChainConfig
    require_inputs : bool, default True
        Missing input images, parameter table or measurement files are errors; with False (to
        check a config before its data exist) they are listed in ``RunPlan.warnings``.

    Raises
    ------
    InputError
        No input image, or an ``inputs.images`` glob matching no file (without ``require_inputs``
        only where the glob's folder exists: a folder not there yet is a warning); quicklook bands
        (``steps.quicklook.bands``) beyond the band count of an existing input image; two scenes
        with the same output name; an output that would overwrite an input
        (:class:`~brdfcorr.io.paths.InputOverwriteError` of :func:`~brdfcorr.io.paths.check_outputs`);
        a missing parameter table or measurement file.
    OutputError
        Two outputs of the run are the same file, or an output is no regular file.
    ParameterError
        An invalid parameter table file (or fitted table reused by ``outputs.existing: skip``).
    """
    images, notes = _images(config, require_inputs)
    output_dir = config.resolve(config.outputs.directory)
    scenes = _plan_scenes(config, images, output_dir)
    _check_quicklook_bands(config, scenes)
    sources, fit_output, parameter_notes = _parameter_sources(config, output_dir, require_inputs)
    report = output_dir / config.outputs.report
    _check_outputs(config, scenes, report, fit_output)
    scenes = _redo_stale(config, scenes, fit_output)
    missing = tuple(notes + parameter_notes)  # before the uncertainty notes: files not found
    if not parameter_notes:  # the table's files exist
        notes += _uncertainty_notes(config, fit_output)
    return RunPlan(config, tuple(scenes), output_dir, report, fit_output, tuple(sources),
                   tuple(notes + parameter_notes), missing)


def _uncertainty_notes(config: ChainConfig, fit_output: Path | None) -> list[str]:
    """A warning when ``outputs.uncertainty`` is on and classes of the planned table have no
    ``fit:`` covariance: their pixels are NaN in the uncertainty raster (docs/uncertainty.md)."""
    table = planned_table(config, fit_output) if config.outputs.uncertainty else None
    if table is None:  # no uncertainty raster, or the fit step makes the table (with covariances)
        return []
    # A library material has its published errors (correction.uncertainty.material_covariance).
    bare = [entry.label for entry in table.classes if entry.fit is None and entry.material is None]
    if not bare:
        return []
    return [f"outputs.uncertainty: {', '.join(bare)} have no fit: block (covariance) in the parameter "
            "table; their pixels are NaN in the uncertainty raster"]


# ---------------------------------------------------------------------------------------- scenes
def _images(config: ChainConfig, require_inputs: bool) -> tuple[list[Path], list[str]]:
    """The input images (globs expanded, duplicates dropped) and notes on patterns matching nothing."""
    images, notes, typo = [], [], False
    for item in config.inputs.images:
        pattern = str(config.resolve(item))
        if glob.has_magic(pattern):
            matches = sorted(Path(p) for p in glob.glob(pattern) if Path(p).is_file())
            if not matches:
                notes.append(f"inputs.images: {item!r} matches no file")
                typo = typo or _glob_root(pattern).is_dir()
            images += matches
        else:
            images.append(Path(pattern))
    images = list(dict.fromkeys(images))  # as given: a link stays a link ({dir} is its directory)
    # A pattern matching nothing is a typo, not an empty batch: an error, also without
    # require_inputs (validate, --dry-run) where its folder exists; only the data of a folder
    # that does not exist yet may be missing there (a warning).
    if not images:
        message = f"inputs.images matches no file ({', '.join(config.inputs.images)})"
        if require_inputs or typo:
            raise InputError(f"{config.source}: {message}")
        notes = [message]
    elif notes and (require_inputs or typo):
        raise InputError(f"{config.source}: {'; '.join(notes)} (fix or remove the pattern)")
    return images, notes


def _glob_root(pattern: str) -> Path:
    """The folder of a glob pattern up to its first wildcard (``data/*/x.tif`` -> ``data``)."""
    parts = Path(pattern).parts
    fixed = next(index for index, part in enumerate(parts) if glob.has_magic(part))
    return Path(*parts[:fixed]) if fixed else Path()


def _check_quicklook_bands(config: ChainConfig, scenes: list[Scene]) -> None:
    """Refuse quicklook bands beyond the band count of an input image (read from the file's header),
    before anything is corrected: one band list serves the whole batch, so an image with fewer
    bands means the setting is wrong, as a glob typo is. Images that are missing or unreadable are
    left to their scene (which fails on them)."""
    step = config.steps.quicklook
    if step is None or step.bands is None:  # chosen by wavelength per image
        return
    needed = max(step.bands)
    short = []
    for scene in scenes:
        if not scene.image.is_file():  # missing (the scene fails) or no regular file: not opened here
            continue
        try:
            with rasterio.open(scene.image) as dataset:
                count = dataset.count
        except (OSError, rasterio.errors.RasterioError):
            continue
        if count < needed:
            short.append(f"{scene.image} has {count}")
    if short:
        more = f" (and {len(short) - 1} more)" if len(short) > 1 else ""
        raise InputError(
            f"{config.source}: steps.quicklook.bands {list(step.bands)} needs {needed} bands, but image "
            f"{short[0]}{more}; choose bands of every image"
        )


def _scene_name(config: ChainConfig, image: Path, shared_stems=frozenset()) -> str:
    regex = config.inputs.scene_regex
    if regex is None:  # the stem, qualified by the directory when several images share it
        return f"{image.parent.name}_{image.stem}" if image.stem in shared_stems else image.stem
    match = re.search(regex, image.name)
    if match is None or not match.group("scene"):
        raise InputError(f"inputs.scene_regex {regex!r} does not match image file name {image.name!r}")
    return match.group("scene")


def _plan_scenes(config: ChainConfig, images: list[Path], output_dir: Path) -> list[Scene]:
    """One scene per image; no two scenes may write the same file name (:func:`_check_outputs` then
    checks every output against every input and output by file identity)."""
    stems = [image.stem for image in images]
    shared = frozenset(stem for stem in stems if stems.count(stem) > 1)
    scenes, writers = [], {}
    for index, image in enumerate(images):
        scene = _plan_scene(config, image, shared, output_dir)
        for path in scene.outputs.values():
            if path in writers and writers[path][0] != index:  # one scene's own outputs: _check_outputs
                raise InputError(
                    f"outputs: scenes {writers[path][1]} and {scene.name} would both write {path}; use {{scene}} or "
                    "{stem} in the output naming patterns, or a scene_regex giving distinct names"
                )
            writers[path] = (index, scene.name)
        scenes.append(scene)
    return scenes


def _plan_scene(config: ChainConfig, image: Path, shared_stems: frozenset, output_dir: Path) -> Scene:
    angles = config.inputs.angles
    try:
        name = _scene_name(config, image, shared_stems)
    except InputError as error:
        return Scene(image.stem, image, Path(), angles.kind, "", {}, {}, "fail", str(error))

    def fill(pattern: str) -> str:
        return format_pattern(pattern, image, name)

    classes = config.resolve(fill(config.inputs.classes))  # not resolved: the user's paths, in messages too
    angle_source = fill(angles.path)
    if angles.kind != "solar":  # the solar source is a time, not a file
        angle_source = str(config.resolve(angle_source))
    slope_aspect, dem = (None if pattern is None else config.resolve(fill(pattern))
                         for pattern in (config.inputs.slope_aspect, config.inputs.dem))
    outputs = _output_paths(config, output_dir, fill, name)
    scene = Scene(name, image, classes, angles.kind, angle_source, dict(angles.options), outputs,
                  slope_aspect=slope_aspect, dem=dem)
    action, reason = _action(config, scene)
    scene = dataclasses.replace(scene, action=action, reason=reason)
    return dataclasses.replace(scene, fingerprint=scene_fingerprint(scene, config))


def _output_paths(config: ChainConfig, output_dir: Path, fill, name: str) -> dict[str, Path]:
    naming, steps, outputs = config.outputs, config.steps, {}
    if steps.correct is not None:
        outputs["corrected"] = output_dir / fill(naming.naming)
        if steps.correct.qa:
            outputs["qa"] = output_dir / fill(naming.qa_naming)
        if naming.uncertainty:
            outputs["uncertainty"] = output_dir / fill(naming.uncertainty_naming)
    if steps.assess is not None:  # the figure's name: brdfcorr.plot.assess.write_assessment_figures
        outputs["assess"] = output_dir / f"{name}_assess.json"
        outputs["assess_profiles"], = figure_paths(output_dir, prefix=f"{name}_assess")
    if steps.quicklook is not None:
        outputs["quicklook"] = output_dir / fill(naming.quicklook_naming)
    return outputs


def _action(config: ChainConfig, scene: Scene) -> tuple[str, str]:
    """(action, reason) from the files alone; :func:`_redo_stale` then checks the skipped scenes."""
    missing = [f"{role} {path}" for role, path in scene.inputs() if not path.exists()]
    if missing:
        return "fail", "missing input: " + ", ".join(missing)
    existing = config.outputs.existing
    if scene.outputs and all(path.exists() for path in scene.outputs.values()):
        if existing == "skip":
            return "skip", "complete outputs exist"
        if existing == "error":
            return "fail", "outputs exist (outputs.existing: error)"
    return "run", ""


# ------------------------------------------------------------------------------------ parameters
def _parameter_sources(config: ChainConfig, output_dir: Path,
                       require_inputs: bool) -> tuple[list[str], Path | None, list[str]]:
    """(the parameter sources in words, the fit step's output, notes on missing files)."""
    sources = [f"material {material} as class {class_id}" for class_id, material in config.parameters.materials.items()]
    sources += [f"inline {entry.label}" for entry in config.parameters.classes]
    notes = []
    if config.parameters.table is not None:
        table_path = config.resolve(config.parameters.table)
        if table_path.exists() or require_inputs:
            ParameterTable.load(table_path)  # fail now on a missing or invalid table
        else:
            notes.append(f"parameters.table: {table_path} does not exist")
        sources.append(f"table {table_path}")
    step = config.steps.fit
    if step is None:
        return sources, None, notes
    fit_output = output_dir / step.output
    if step.source == "goniometer":
        for item in step.measurements:
            path = config.resolve(item.file)
            if not path.exists():
                if require_inputs:
                    raise InputError(f"steps.fit.measurements: file {path} does not exist")
                notes.append(f"steps.fit.measurements: {path} does not exist")
        sources.append(f"fit from goniometer measurements -> {fit_output}")
    else:
        model = f"model {step.model}" if step.model else (
            f"model {STRATA_MODEL} on NDVI strata class maps, else {DEFAULT_MODEL}")
        sources.append(f"fit from the imagery of the run's scenes ({model}) -> {fit_output}")
    return sources, fit_output, notes


def _check_outputs(config: ChainConfig, scenes: list[Scene], report: Path, fit_output: Path | None) -> None:
    """The output guard over the whole run (:func:`brdfcorr.io.paths.check_outputs`): every file
    the run writes against every file it reads (every scene's inputs, the chain config, the
    parameter table, measurement files) and against each other, whatever each scene's action."""
    written = [(f"outputs: {key} output {path} of scene {scene.name}", path)
               for scene in scenes for key, path in scene.outputs.items()]
    if config.outputs.format == "ENVI":  # the header and .aux.xml beside each corrected data file
        written += [(f"outputs: corrected output's sidecar {final} of scene {scene.name}", final)
                    for scene in scenes if "corrected" in scene.outputs
                    for _, final in envi_sidecars(scene.outputs["corrected"], scene.outputs["corrected"])]
    written.append((f"outputs.report {report}", report))
    if fit_output is not None:
        written.append((f"steps.fit.output {fit_output}", fit_output))
    read = [(f"the {role} of scene {scene.name}", path) for scene in scenes for role, path in scene.inputs()]
    if os.path.isfile(config.source):  # a config made in Python has a label, not a file
        read.append(("the chain config", Path(config.source)))
    if config.parameters.table is not None:
        read.append(("parameters.table", config.resolve(config.parameters.table)))
    if config.steps.fit is not None and config.steps.fit.source == "goniometer":
        read += [("steps.fit.measurements", config.resolve(item.file)) for item in config.steps.fit.measurements]
    try:
        check_outputs(written, read)
    except InputOverwriteError as clash:
        raise InputError(f"{config.source}: {clash.output_name} would overwrite an input (the same file as "
                         f"{clash.input_name} {clash.input})") from None
    except OutputError as error:  # two outputs on one file, an output that is no regular file
        raise OutputError(f"{config.source}: {error}") from None


def configured_table(config: ChainConfig) -> ParameterTable:
    """The parameters given in the config: built-in materials, inline classes, the table file
    (later wins for a class id)."""
    entries = []
    for class_id, name in sorted(config.parameters.materials.items()):
        entries.append(ClassEntry(id=class_id, material=name))  # the library's model and values
    tables = [ParameterTable(classes=entries), ParameterTable(classes=list(config.parameters.classes))]
    if config.parameters.table is not None:
        tables.append(ParameterTable.load(config.resolve(config.parameters.table)))
    return merge_tables(tables)


def reuses_fit(config: ChainConfig, fit_output: Path | None) -> bool:
    """Whether the run reuses the fitted table of an earlier run (resume) instead of fitting."""
    return fit_output is not None and config.outputs.existing == "skip" and fit_output.exists()


def planned_table(config: ChainConfig, fit_output: Path | None) -> ParameterTable | None:
    """The parameter table the run will use, as known before it runs: the configured table and a
    reused fitted table; None when the fit step makes a new table."""
    if config.steps.fit is None:
        return configured_table(config)
    if not reuses_fit(config, fit_output):
        return None
    return merge_tables([configured_table(config), ParameterTable.load(fit_output)])


def _redo_stale(config: ChainConfig, scenes: list[Scene], fit_output: Path | None) -> list[Scene]:
    """The scenes, with skipped ones turned to ``run`` when their outputs were not made with the
    run's parameter table, inputs and settings."""
    if not any(scene.action == "skip" and "corrected" in scene.outputs for scene in scenes):
        return scenes
    table_file = config.parameters.table
    if table_file is not None and not config.resolve(table_file).exists():
        return scenes  # without require_inputs only: the run stops before any scene (a plan warning)
    table = planned_table(config, fit_output)
    return [_unless_stale(scene, table) for scene in scenes]


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
    if tags.get("brdf_fingerprint") != hashlib.sha256(scene.fingerprint.encode()).hexdigest():
        return dataclasses.replace(scene, action="run", reason=_what_changed(tags, scene.fingerprint))
    return scene


#: The outputs of a scene that are rasters (checked as a fresh write is before a resume skips them).
_RASTERS = ("corrected", "qa", "uncertainty")


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

    It holds the input files' (image, class map, angles, terrain source) path (as given), size,
    modification time [ns] and content digest (:func:`brdfcorr.io.files.content_digest`; the
    acquisition time of a ``solar`` angle source), the angle source's
    kind and options, the other ``inputs`` settings (wavelengths, class lookup, ...), the reference
    geometry, the correct step's options (limits, terrain, ...; not ``qa``: the QA and uncertainty
    rasters are extra outputs of the same pass, their presence is checked as a file's), the output
    format (compression, COG, ENVI interleave) and the brdfcorr version. The parameter table is recorded in
    full apart from it (tag ``brdf_parameter_table_content``, :func:`planned_table`): a table from
    the fit step is only known once the run has fitted it.
    """
    inputs = {role: _file_state(path) for role, path in scene.inputs()}
    if scene.angles_kind == "solar":
        inputs["angles"] = {"time": scene.angles}
    correct = None if config.steps.correct is None else config.steps.correct.model_dump(mode="json", exclude={"qa"})
    if correct is not None:  # the defaults of later options are not recorded: older outputs stay current
        if correct["terrain"] is None:  # a flat correction records what it did before terrain
            del correct["terrain"]
        if correct["factor_at"] == "pixels":
            del correct["factor_at"]
    document = {
        "brdfcorr": __version__,
        "inputs": inputs,
        "angle source": {"kind": scene.angles_kind, "options": scene.angle_options},
        "settings": config.inputs.model_dump(mode="json", exclude={"images", "scene_regex", "angles", "classes",
                                                                    "slope_aspect", "dem"}),
        "reference": None if config.reference is None else config.reference.model_dump(mode="json"),
        "correct": correct,
        "format": config.outputs.model_dump(mode="json", include={"format", "compress", "cog", "interleave"},
                                            exclude_none=True),
    }
    return json.dumps(document, sort_keys=True, separators=(",", ":"), default=str)


def _file_state(path: Path) -> dict:
    """A file's identity in a fingerprint: path (as given), size [bytes], modification time [ns] and
    content (:func:`brdfcorr.io.files.content_digest`: an edit in place that kept the size and the
    time changes it). Only regular files are read (a FIFO would block)."""
    try:
        status = os.stat(path)
        digest = content_digest(path) if stat.S_ISREG(status.st_mode) else None
    except OSError:
        return {"path": str(path)}
    return {"path": str(path), "size": status.st_size, "mtime_ns": status.st_mtime_ns, "content": digest}


#: How a reason names a part of a fingerprint.
_PARTS = {"brdfcorr": "brdfcorr version", "angle source": "angle source", "settings": "inputs settings",
          "reference": "reference geometry", "correct": "steps.correct", "format": "output format"}


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
