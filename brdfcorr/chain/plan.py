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
fresh write is (:func:`brdfcorr.io.commit.check_complete`: one cut short after the run is redone); it
is still redone when its corrected image records (provenance tag ``brdf_parameter_table_content``)
another parameter table than the one this run will use (:func:`brdfcorr.chain.resume.planned_table`),
or another fingerprint (tags ``brdf_fingerprint``, ``brdf_fingerprint_content``) than the one this
run would write (:func:`brdfcorr.chain.resume.scene_fingerprint`: the input files' path, size,
modification time and content digest, the reference geometry, limits and other settings, the
brdfcorr version). When the fit step makes a new table,
that table is not known before the run, and such scenes are redone.

Before anything runs, every file the run writes (scene outputs, run report, fitted table) is
checked against every file it reads (every scene's inputs, the chain config, the parameter table,
measurement files) and against each other (:func:`brdfcorr.io.paths.check_outputs`). Paths keep
the form the config gives them (a scene image given as a link has ``{dir}`` of the link); file
identity is only compared in that check.

The scenes are expanded in :mod:`brdfcorr.chain.scenes`, the resume checks and fingerprints are
in :mod:`brdfcorr.chain.resume`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from brdfcorr.chain.config import ChainConfig
from brdfcorr.chain.resume import fit_fingerprint, planned_table, redo_stale, reuses_fit, scene_fingerprint
from brdfcorr.chain.scenes import Scene, check_quicklook_bands, input_images, plan_scenes
from brdfcorr.errors import InputError, OutputError
from brdfcorr.fit.settings import DEFAULT_MODEL, STRATA_MODEL
from brdfcorr.io.paths import InputOverwriteError, SidecarClashError, check_outputs, envi_sidecars
from brdfcorr.params import ParameterTable

__all__ = ["RunPlan", "plan_run"]


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
    #: What the fitted table depends on (:func:`~brdfcorr.chain.resume.fit_fingerprint`; None
    #: without a fit step), and whether the run reuses the table an earlier run fitted from the same.
    fit_fingerprint: str | None = None
    reuses_fit: bool = False

    def missing_inputs(self) -> list[str]:
        """Every input the run would miss, in words: :attr:`missing`, then each scene failing for a
        missing input (``scene NAME: missing input: ...``). Empty when the chain can run."""
        scenes = [f"scene {scene.name}: {scene.reason}" for scene in self.scenes
                  if scene.action == "fail" and scene.reason.startswith("missing input")]
        return [*self.missing, *scenes]

    @property
    def steps(self) -> list[str]:
        steps = self.config.steps
        names = ("strata", "fit", "correct", "assess", "quicklook")
        return [name for name in names if getattr(steps, name) is not None]

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
    images, notes = input_images(config, require_inputs)
    output_dir = config.resolve(config.outputs.directory)
    scenes = plan_scenes(config, images, output_dir, scene_fingerprint)
    check_quicklook_bands(config, scenes)
    sources, fit_output, parameter_notes = _parameter_sources(config, output_dir, require_inputs)
    report = output_dir / config.outputs.report
    _check_outputs(config, scenes, report, fit_output)
    fingerprint = fit_fingerprint(config, scenes) if not parameter_notes else None  # its files exist
    reused = fit_output if reuses_fit(config, fit_output, report, fingerprint) else None
    if reused is not None:
        sources[-1] = f"the fitted table {reused}, reused: its fit settings and inputs are unchanged"
    scenes = redo_stale(config, scenes, reused, report)
    missing = tuple(notes + parameter_notes)  # before the uncertainty notes: files not found
    if not parameter_notes:  # the table's files exist
        notes += _uncertainty_notes(config, reused) + _classes_given_twice(config)
    return RunPlan(config, tuple(scenes), output_dir, report, fit_output, tuple(sources),
                   tuple(notes + parameter_notes), missing, fingerprint, reused is not None)


def _uncertainty_notes(config: ChainConfig, reused: Path | None) -> list[str]:
    """A warning when ``outputs.uncertainty`` is on and classes of the planned table (with the
    fitted table it ``reused``) have no ``fit:`` covariance: their pixels are NaN in the
    uncertainty raster (docs/uncertainty.md)."""
    table = planned_table(config, reused) if config.outputs.uncertainty else None
    if table is None:  # no uncertainty raster, or the fit step makes the table (with covariances)
        return []
    bare = table.classes_without_errors()
    if not bare:
        return []
    return [f"outputs.uncertainty: {', '.join(bare)} have no fit: block (covariance) in the parameter "
            "table; their pixels are NaN in the uncertainty raster"]


# ------------------------------------------------------------------------------------ parameters
def _parameter_sources(config: ChainConfig, output_dir: Path,
                       require_inputs: bool) -> tuple[list[str], Path | None, list[str]]:
    """(the parameter sources in words, the fit step's output, notes on missing files)."""
    sources = [f"material {material} as class {class_id}" for class_id, material in config.parameters.materials.items()]
    sources += [f"inline {entry.label}" for entry in config.parameters.classes]
    notes = []
    table_path = config.table_path()
    if config.parameters.table is not None and table_path is None:
        sources.append(f"coefficient set {config.parameters.table}")
    elif table_path is not None:
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


def _classes_given_twice(config: ChainConfig) -> list[str]:
    """A note per class id that more than one of ``parameters``' sources gives: the last source
    (materials, inline classes, the table file: :func:`brdfcorr.chain.resume.configured_table`)
    is used, and the others' entries of that class are not."""
    given = {"parameters.materials": set(config.parameters.materials),
             "parameters.classes": {entry.id for entry in config.parameters.classes}}
    table = config.given_table()
    if table is not None:
        given["parameters.table"] = set(table.class_ids)
    sources: dict[int, list[str]] = {}
    for source, ids in given.items():
        for class_id in ids:
            sources.setdefault(class_id, []).append(source)
    return [f"class {class_id} is given in {' and '.join(names)}: {names[-1]}'s entry is used"
            for class_id, names in sorted(sources.items()) if len(names) > 1]


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
    table_path = config.table_path()
    if table_path is not None:
        read.append(("parameters.table", table_path))
    if config.steps.fit is not None and config.steps.fit.source == "goniometer":
        read += [("steps.fit.measurements", config.resolve(item.file)) for item in config.steps.fit.measurements]
    try:
        check_outputs(written, read)
    except SidecarClashError as clash:  # a file GDAL would read with an input, not there yet
        raise InputError(f"{config.source}: {clash}") from None
    except InputOverwriteError as clash:
        raise InputError(f"{config.source}: {clash.output_name} would overwrite an input (the same file as "
                         f"{clash.input_name} {clash.input})") from None
    except OutputError as error:  # two outputs on one file, an output that is no regular file
        raise OutputError(f"{config.source}: {error}") from None
