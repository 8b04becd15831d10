"""One chain run: sources -> fit? -> normalize -> sinks, for many scenes, with a run report.

:func:`plan_run` expands a :class:`~brdfcorr.workflow.config.ChainConfig` into scenes (image, angle
source, class map and output names for every input image) and says what would happen to each
(``run``, ``skip`` because its complete outputs exist, ``fail`` because an input is missing or the
outputs exist under ``existing: error``). :func:`run_chain` then

1. builds the parameter table: built-in materials, the table file, the ``fit`` step (from
   goniometer CSVs with :func:`brdfcorr.fit.goniometer.fit_measurements` or from the imagery with
   :func:`brdfcorr.fit.classes.fit_classes`), merged in that order (later wins for a class id);
2. normalizes every scene with :func:`brdfcorr.correct.correct_files` (lazy, chunked, atomic
   writes, QA counts) and writes a before/after quicklook;
3. writes the run report (JSON): inputs, parameter table and its sources, versions, timings,
   per-scene QA counts and errors.

A failing scene is recorded (message and error type) and the others go on. Outputs appear complete
or not at all (temporary names renamed when complete), so a scene whose outputs all exist is
complete: ``existing: skip`` resumes an interrupted run. A complete scene whose corrected image was
made with another parameter table (its provenance tag) is redone, not skipped.

Execution engines (``engine.scheduler``):

``threads``       scenes one after another, each scene's chunks on ``workers`` threads
``synchronous``   everything in the calling thread
``processes``     ``workers`` scenes at once in a process pool (``threads_per_worker`` each)
``distributed``   scenes as tasks on a ``dask.distributed`` cluster (``address``, or a local
                  cluster of ``workers`` processes); each task runs its scene's chunks on
                  ``threads_per_worker`` local threads and writes its own files (so workers need
                  the file system of the inputs and outputs)

Scenes are the unit of parallelism in the ``processes`` and ``distributed`` engines: a GeoTIFF is
written by one process (no cross-process file locks) and a batch of many scenes keeps every worker
busy.

Nothing here prints: progress goes to a callback ``progress(event, info)`` with events ``"plan"``
(``{"scenes": n_to_run}``), ``"fit"`` (``{"classes": [...]}``) and ``"scene"`` (the scene's result).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import glob
import json
import platform
import re
import threading
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import dask
import numpy as np

from brdfcorr.workflow.config import ChainConfig, format_pattern
from brdfcorr.errors import BrdfcorrError, InputError
from brdfcorr.io.files import atomic_path
from brdfcorr.fit.classes import GuardRails
from brdfcorr.params import ClassEntry, ParameterTable, merge_tables
from brdfcorr.workflow.tasks import SceneFiles, correct_files, fit_class_files, fit_measurement_file

__all__ = [
    "Scene",
    "RunPlan",
    "RunReport",
    "plan_run",
    "build_table",
    "run_chain",
    "process_scene",
    "write_quicklook",
    "versions",
]

Progress = Callable[[str, dict], None]


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
        ``corrected`` and, when enabled, ``qa`` and ``quicklook``.
    action : {"run", "skip", "fail"}
        What the run will do; ``reason`` says why for ``skip`` and ``fail``.
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

    def describe(self) -> dict:
        """JSON-friendly description (for the report and ``--dry-run``)."""
        return {
            "scene": self.name,
            "image": str(self.image),
            "angles": {"kind": self.angles_kind, "source": self.angles, **(
                {"options": self.angle_options} if self.angle_options else {})},
            "classes": str(self.classes),
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

    @property
    def steps(self) -> list[str]:
        steps = self.config.steps
        return [name for name in ("fit", "correct", "quicklook") if getattr(steps, name) is not None]

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


@dataclass
class RunReport:
    """The outcome of :func:`run_chain`; :meth:`to_dict` is what the report file holds."""

    plan: RunPlan
    table: ParameterTable | None
    scenes: list[dict] = field(default_factory=list)
    fit: dict | None = None
    timings: dict = field(default_factory=dict)
    started: str = ""
    path: Path | None = None

    @property
    def n_failed(self) -> int:
        return sum(result["status"] == "failed" for result in self.scenes)

    @property
    def n_ok(self) -> int:
        return sum(result["status"] == "ok" for result in self.scenes)

    @property
    def n_skipped(self) -> int:
        return sum(result["status"] == "skipped" for result in self.scenes)

    @property
    def ok(self) -> bool:
        """True when no scene failed."""
        return self.n_failed == 0

    def to_dict(self) -> dict:
        config = self.plan.config
        return {
            "brdfcorr_run": {
                "name": config.name,
                "config": config.source,
                "config_content": config.to_dict(),
                "started": self.started,
                "steps": self.plan.steps,
            },
            "versions": versions(config.engine.scheduler == "distributed"),
            "engine": config.engine.model_dump(),
            "inputs": [
                {key: value for key, value in scene.describe().items() if key not in ("action", "reason")}
                for scene in self.plan.scenes
            ],
            "parameters": {
                "sources": list(self.plan.table_sources),
                "table": None if self.table is None else self.table.to_dict(),
            },
            "reference": None if config.reference is None else config.reference.model_dump(),
            "fit": self.fit,
            "scenes": self.scenes,
            "summary": {
                "scenes": len(self.scenes), "ok": self.n_ok, "skipped": self.n_skipped,
                "failed": self.n_failed,
            },
            "timings": self.timings,
        }


def versions(distributed: bool = False) -> dict[str, str]:
    """Versions of brdfcorr and the libraries a run depends on."""
    import rasterio
    import rioxarray
    import xarray

    from brdfcorr import __version__

    found = {
        "brdfcorr": __version__, "python": platform.python_version(), "numpy": np.__version__,
        "xarray": xarray.__version__, "dask": dask.__version__, "rasterio": rasterio.__version__,
        "gdal": rasterio.__gdal_version__, "rioxarray": rioxarray.__version__,
    }
    if distributed:
        import distributed as dist

        found["distributed"] = dist.__version__
    return found


# ------------------------------------------------------------------------------------------ plan
def _expand_images(config: ChainConfig) -> tuple[list[Path], list[str]]:
    images, notes = [], []
    for item in config.inputs.images:
        pattern = str(config.resolve(item))
        if glob.has_magic(pattern):
            matches = sorted(Path(p) for p in glob.glob(pattern) if Path(p).is_file())
            if not matches:
                notes.append(f"inputs.images: {item!r} matches no file")
            images += matches
        else:
            images.append(Path(pattern))
    return list(dict.fromkeys(path.resolve() for path in images)), notes


def _scene_name(config: ChainConfig, image: Path, shared_stems=frozenset()) -> str:
    regex = config.inputs.scene_regex
    if regex is None:  # the stem, qualified by the directory when several images share it
        return f"{image.parent.name}_{image.stem}" if image.stem in shared_stems else image.stem
    match = re.search(regex, image.name)
    if match is None or not match.group("scene"):
        raise InputError(f"inputs.scene_regex {regex!r} does not match image file name {image.name!r}")
    return match.group("scene")


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
        No input image, or (with ``require_inputs``) an ``inputs.images`` glob matching no file;
        two scenes with the same output name; an output that would overwrite an input; a missing
        parameter table or measurement file.
    ParameterError
        An invalid parameter table file.
    """
    images, notes = _expand_images(config)
    if not images:
        message = f"inputs.images matches no file ({', '.join(config.inputs.images)})"
        if require_inputs:
            raise InputError(f"{config.source}: {message}")
        notes = [message]
    elif notes and require_inputs:  # a pattern that matches nothing is a typo, not an empty batch
        raise InputError(f"{config.source}: {'; '.join(notes)} (fix or remove the pattern)")
    outputs_config, steps = config.outputs, config.steps
    output_dir = config.resolve(outputs_config.directory).resolve()
    angles = config.inputs.angles
    scenes, seen = [], {}
    stems = [image.stem for image in images]
    shared = frozenset(stem for stem in stems if stems.count(stem) > 1)
    for image in images:
        try:
            name = _scene_name(config, image, shared)
        except InputError as error:
            scenes.append(Scene(image.stem, image, Path(), angles.kind, "", {}, {}, "fail", str(error)))
            continue
        fill = lambda pattern: format_pattern(pattern, image, name)  # noqa: E731
        classes = config.resolve(fill(config.inputs.classes)).resolve()
        angle_source = fill(angles.path)
        if angles.kind != "solar":  # the solar source is a time, not a file
            angle_source = str(config.resolve(angle_source).resolve())
        outputs = {}
        if steps.correct is not None:
            outputs["corrected"] = output_dir / fill(outputs_config.naming)
            if steps.correct.qa:
                outputs["qa"] = output_dir / fill(outputs_config.qa_naming)
        if steps.quicklook is not None:
            outputs["quicklook"] = output_dir / fill(outputs_config.quicklook_naming)
        for key, path in outputs.items():
            if path in seen:
                raise InputError(
                    f"outputs: scenes {seen[path]} and {name} would both write {path}; use {{scene}} or "
                    "{stem} in the output naming patterns, or a scene_regex giving distinct names"
                )
            if path in (image, classes) or (angles.kind != "solar" and str(path) == angle_source):
                raise InputError(f"outputs: {key} output {path} of scene {name} would overwrite an input")
            seen[path] = name
        action, reason = "run", ""
        missing = [f"{role} {path}" for role, path in (("image", image), ("class map", classes)) if not path.exists()]
        if angles.kind != "solar" and not Path(angle_source).exists():
            missing.append(f"angles {angle_source}")
        if missing:
            action, reason = "fail", "missing input: " + ", ".join(missing)
        elif outputs and all(path.exists() for path in outputs.values()):
            if outputs_config.existing == "skip":
                action, reason = "skip", "complete outputs exist"
            elif outputs_config.existing == "error":
                action, reason = "fail", "outputs exist (outputs.existing: error)"
        scenes.append(Scene(name, image, classes, angles.kind, angle_source, dict(angles.options), outputs, action, reason))

    sources = []
    for class_id, material in config.parameters.materials.items():
        sources.append(f"material {material} as class {class_id}")
    for entry in config.parameters.classes:
        sources.append(f"inline {entry.label}")
    if config.parameters.table is not None:
        table_path = config.resolve(config.parameters.table)
        if table_path.exists() or require_inputs:
            ParameterTable.load(table_path)  # fail now on a missing or invalid table
        else:
            notes.append(f"parameters.table: {table_path} does not exist")
        sources.append(f"table {table_path}")
    fit_output = None
    if steps.fit is not None:
        fit_output = output_dir / steps.fit.output
        if steps.fit.source == "goniometer":
            for item in steps.fit.measurements:
                path = config.resolve(item.file)
                if not path.exists():
                    if require_inputs:
                        raise InputError(f"steps.fit.measurements: file {path} does not exist")
                    notes.append(f"steps.fit.measurements: {path} does not exist")
            sources.append(f"fit from goniometer measurements -> {fit_output}")
        else:
            sources.append(f"fit from the imagery of the run's scenes -> {fit_output}")
    report = output_dir / outputs_config.report
    inputs = {scene.image for scene in scenes} | {scene.classes for scene in scenes}
    if config.parameters.table is not None:
        inputs.add(config.resolve(config.parameters.table).resolve())
    for key, path in (("outputs.report", report), ("steps.fit.output", fit_output)):
        if path is not None and path.resolve() in inputs:
            raise InputError(f"{config.source}: {key} {path} would overwrite an input")
    return RunPlan(config, tuple(scenes), output_dir, report, fit_output, tuple(sources), tuple(notes))


# ----------------------------------------------------------------------------------- parameters
def _materials_table(config: ChainConfig) -> ParameterTable:
    """Built-in materials, then the inline classes (which win for a shared id)."""
    from brdfcorr.models.materials import load_material

    entries = []
    for class_id, name in sorted(config.parameters.materials.items()):
        material = load_material(name)
        entries.append(ClassEntry(id=class_id, name=material.name, model=material.model.name,
                                  params=dict(material.params)))
    return merge_tables([ParameterTable(classes=entries), ParameterTable(classes=list(config.parameters.classes))])


def _scene_files(scene: Scene) -> SceneFiles:
    return SceneFiles(scene.image, scene.classes, scene.angles, scene.angles_kind, dict(scene.angle_options),
                      scene.name)


def _fit_imagery(plan: RunPlan) -> tuple[ParameterTable, dict]:
    config = plan.config
    step = config.steps.fit
    failed = [{"scene": s.name, "reason": s.reason} for s in plan.scenes if s.action == "fail"]
    candidates = [_scene_files(s) for s in plan.scenes if s.action != "fail"]
    reasons = "".join(f"; {s['scene']}: {s['reason']}" for s in failed)
    if not candidates:
        raise InputError(f"steps.fit: no scene could be opened for the imagery fit{reasons}")
    names = {class_id: name for class_id, name in config.parameters.materials.items()}
    names.update(step.names)
    try:
        fit = fit_class_files(
            candidates, step.model, class_models=step.class_models, names=names, fixed=step.fixed,
            max_samples=step.max_samples, seed=step.seed, reflectance_scale=step.reflectance_scale,
            guard=GuardRails(min_samples=step.min_samples, min_vza_spread=step.min_vza_spread),
            fallback=step.fallback, chunks=config.engine.chunk, wavelengths=config.inputs.wavelengths,
            skip_unreadable=True,
        )
    except InputError as error:
        raise InputError(f"steps.fit: {error}{reasons}") from None
    report = fit.report()
    report["scenes_left_out"] = failed + report["scenes_left_out"]
    return fit.table, report


def _fit_goniometer(plan: RunPlan) -> tuple[ParameterTable, dict]:
    config = plan.config
    table, classes, notes = ParameterTable(), [], []
    for item in config.steps.fit.measurements:
        fit = fit_measurement_file(
            config.resolve(item.file), item.model, fixed=item.fixed, initial=item.initial,
            min_phi=item.min_phi, max_phi=item.max_phi, max_zenith=item.max_zenith,
        )
        notes += [f"class {item.class_id} ({item.name}): {note}" for note in fit.warnings]
        table = table.with_class(fit.table_entry(item.class_id, item.name))
        classes.append({
            "class_id": item.class_id, "name": item.name, "model": item.model, "file": str(fit.path),
            "n_measurements": len(fit.fitted), "fits": fit.report(),
        })
    return table, {"source": "goniometer", "classes": classes, "warnings": notes}


def build_table(plan: RunPlan, progress: Progress | None = None) -> tuple[ParameterTable, dict | None]:
    """The run's parameter table: materials, then the table file, then the fit step (later wins).

    The fitted table is written to the fit step's ``output`` in the output directory; with
    ``outputs.existing: skip`` an existing fitted table is reused (resume), so the scenes of a
    resumed run are all corrected with the same parameters.
    """
    config = plan.config
    tables = [_materials_table(config)]
    if config.parameters.table is not None:
        tables.append(ParameterTable.load(config.resolve(config.parameters.table)))
    fit_report = None
    step = config.steps.fit
    if step is not None:
        if plan.fit_output.exists() and config.outputs.existing == "skip":
            fitted = ParameterTable.load(plan.fit_output)
            fit_report = {"source": step.source, "reused": str(plan.fit_output)}
        else:
            fitted, fit_report = (_fit_imagery if step.source == "imagery" else _fit_goniometer)(plan)
            plan.output_dir.mkdir(parents=True, exist_ok=True)
            fitted.save(plan.fit_output)
            fit_report["output"] = str(plan.fit_output)
        tables.append(fitted)
        if progress is not None:
            progress("fit", {"classes": list(fitted.class_ids), **fit_report})
    table = merge_tables(tables)
    if not len(table) and config.steps.correct is not None:
        raise InputError(f"{config.source}: the parameter table of the run has no class")
    return table, fit_report


# --------------------------------------------------------------------------------------- scenes
_LOCAL_LOCK = threading.Lock()
_LOCAL_DEPTH = 0
_LOCAL_SAVED: dict = {}


@contextlib.contextmanager
def _local_threads(threads: int):
    """Use dask's local threaded scheduler in this process while any scene task runs in it.

    dask's config is process-wide: tasks running side by side in one worker process share one
    setting, counted here, so one finishing task cannot unset it under another.
    """
    global _LOCAL_DEPTH
    with _LOCAL_LOCK:
        if _LOCAL_DEPTH == 0:
            _LOCAL_SAVED.clear()
            _LOCAL_SAVED.update({key: dask.config.get(key, None) for key in ("scheduler", "num_workers")})
            dask.config.set({"scheduler": "threads", "num_workers": threads})
        _LOCAL_DEPTH += 1
    try:
        yield
    finally:
        with _LOCAL_LOCK:
            _LOCAL_DEPTH -= 1
            if _LOCAL_DEPTH == 0:
                dask.config.set(dict(_LOCAL_SAVED))


def process_scene(scene: Scene, table: ParameterTable, config: ChainConfig, *, threads: int | None = None) -> dict:
    """Correct one scene and write its outputs; never raises: failures go into the result.

    Parameters
    ----------
    scene : Scene
    table : ParameterTable
    config : ChainConfig
    threads : int, optional
        Run the scene's chunks on this many local threads (inside process or cluster workers);
        by default the caller's dask scheduler is used.

    Returns
    -------
    dict
        ``scene``, ``status`` (``ok``, ``failed``), ``outputs``, ``qa`` (pixel counts of
        :func:`brdfcorr.correct.qa_counts`), ``reference``, ``seconds`` (per step) and, on failure,
        ``error`` and ``error_type``.
    """
    result = {"scene": scene.name, "image": str(scene.image), "status": "ok",
              "outputs": {key: str(path) for key, path in scene.outputs.items()}}
    seconds = {}
    start = time.perf_counter()
    try:
        with _local_threads(threads) if threads else contextlib.nullcontext():
            if scene.action == "fail":
                raise InputError(scene.reason)
            steps = config.steps
            for path in scene.outputs.values():
                path.parent.mkdir(parents=True, exist_ok=True)
            if steps.correct is not None:
                tick = time.perf_counter()
                summary = _correct(scene, table, config)
                seconds["correct"] = round(time.perf_counter() - tick, 3)
                reference = summary.pop("reference")
                result["reference"] = reference.describe()
                result["qa"] = summary
            if steps.quicklook is not None:
                tick = time.perf_counter()
                write_quicklook(
                    scene.image, scene.outputs["corrected"], scene.outputs["quicklook"], classes=scene.classes,
                    bands=steps.quicklook.bands, percentiles=steps.quicklook.percentiles,
                    max_size=steps.quicklook.max_size, title=scene.name,
                )
                seconds["quicklook"] = round(time.perf_counter() - tick, 3)
    except Exception as error:  # noqa: BLE001 (isolation: a scene's failure must not stop the run)
        result["status"] = "failed"
        result["error"] = str(error) if isinstance(error, BrdfcorrError) else f"{type(error).__name__}: {error}"
        result["error_type"] = type(error).__name__
    seconds["total"] = round(time.perf_counter() - start, 3)
    result["seconds"] = seconds
    return result


def _correct(scene: Scene, table: ParameterTable, config: ChainConfig) -> dict:
    step, outputs = config.steps.correct, config.outputs
    return correct_files(
        scene.image, scene.outputs["corrected"], params=table, classes=scene.classes,
        reference=config.reference, qa_output=scene.outputs.get("qa"), wavelengths=config.inputs.wavelengths,
        extrapolate=step.extrapolate, limits=step.limits, unknown=step.unknown,
        flip_view_azimuth=step.flip_view_azimuth, chunks=config.engine.chunk, compress=outputs.compress,
        cog=outputs.cog, table_source=config.source, angles=scene.angles, angles_kind=scene.angles_kind,
        angle_options=dict(scene.angle_options),
    )


# ------------------------------------------------------------------------------------- quicklook
def _read_small(path: Path, bands: list[int], max_size: int, average: bool = True) -> np.ndarray:
    """Bands of a raster decimated to at most ``max_size`` pixels on its longer side (GDAL
    resampling: average for reflectance, nearest for class maps); nodata as NaN."""
    import rasterio
    from rasterio.enums import Resampling

    with rasterio.open(path) as dataset:
        for band in bands:
            if band > dataset.count:
                raise InputError(f"steps.quicklook.bands: band {band} does not exist in {path} ({dataset.count} bands)")
        scale = max(1.0, max(dataset.height, dataset.width) / max_size)
        shape = (len(bands), max(1, round(dataset.height / scale)), max(1, round(dataset.width / scale)))
        data = dataset.read(bands, out_shape=shape, masked=True,
                            resampling=Resampling.average if average else Resampling.nearest)
    return np.ma.filled(data.astype(np.float64), np.nan)


def write_quicklook(image, corrected, target, *, classes=None, bands=(3, 2, 1), percentiles=(2.0, 98.0),
                    max_size: int = 800, title: str = "") -> Path:
    """Before/after PNG: input and corrected image with the *same* contrast stretch, and the
    across-track profile (column means, relative to the class mean) per class before and after.

    Parameters
    ----------
    image, corrected : path-like
        Input and corrected rasters (same grid).
    target : path-like
        PNG to write (atomically).
    classes : path-like, optional
        Class map for per-class profiles (the three most frequent classes); without it one profile
        of all valid pixels.
    bands : sequence of int
        1-based bands for red, green, blue, or one band (grey).
    percentiles : (float, float)
        Stretch [%] of the input image, per band, applied to both panels.
    max_size : int
        Longest side of the panels [pixels].
    """
    from matplotlib.figure import Figure

    bands = list(bands)
    before = _read_small(Path(image), bands, max_size)
    after = _read_small(Path(corrected), bands, max_size)
    low = np.nanpercentile(before, percentiles[0], axis=(1, 2), keepdims=True)
    high = np.nanpercentile(before, percentiles[1], axis=(1, 2), keepdims=True)
    span = np.where(high > low, high - low, 1.0)

    def display(cube):
        rgb = np.clip((cube - low) / span, 0.0, 1.0)
        rgb = np.where(np.isnan(rgb), 1.0, rgb)  # nodata shown white
        return np.moveaxis(rgb, 0, -1) if len(bands) == 3 else rgb[0]

    figure = Figure(figsize=(12, 7.5), layout="constrained")
    grid = figure.add_gridspec(2, 2, height_ratios=(3, 2))
    label = "bands " + ",".join(map(str, bands))
    for column, (cube, name) in enumerate(((before, "before"), (after, "after (BRDF-normalized)"))):
        axis = figure.add_subplot(grid[0, column])
        axis.imshow(display(cube), cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        axis.set_title(f"{title} {name}".strip())
        axis.set_xticks([])
        axis.set_yticks([])
    axis = figure.add_subplot(grid[1, :])
    brightness_before, brightness_after = np.nanmean(before, axis=0), np.nanmean(after, axis=0)
    groups = [("all pixels", np.isfinite(brightness_before))]
    if classes is not None:
        class_map = _read_small(Path(classes), [1], max_size, average=False)[0]
        if class_map.shape == brightness_before.shape:
            ids, counts = np.unique(class_map[np.isfinite(class_map) & (class_map > 0)], return_counts=True)
            top = ids[np.argsort(counts)[::-1][:3]]
            groups = [(f"class {int(i)}", class_map == i) for i in sorted(top)] or groups
    columns = np.arange(brightness_before.shape[1])
    for index, (name, mask) in enumerate(groups):
        colour = f"C{index}"
        for cube, style, when in ((brightness_before, "--", "before"), (brightness_after, "-", "after")):
            values = np.where(mask, cube, np.nan)
            with warnings.catch_warnings():  # columns without the class: NaN, not a warning
                warnings.simplefilter("ignore", RuntimeWarning)
                profile = np.nanmean(values, axis=0)
                profile = profile / np.nanmean(values)
            axis.plot(columns, profile, style, color=colour, label=f"{name} {when}")
    axis.axhline(1.0, color="0.6", linewidth=0.8)
    axis.set_xlabel("column (across track)")
    axis.set_ylabel("column mean / class mean [-]")
    axis.set_title(f"across-track profile ({label}; dashed: before, solid: after)")
    axis.legend(ncols=3, fontsize="small")
    target = Path(target)
    with atomic_path(target) as temporary:
        figure.savefig(temporary, dpi=90, format="png")
    return target


# -------------------------------------------------------------------------------------------- run
@contextlib.contextmanager
def _executor(config: ChainConfig):
    """(executor or None, threads per scene task): None runs scenes inline on dask's local scheduler."""
    engine = config.engine
    if engine.scheduler in ("threads", "synchronous"):
        with dask.config.set(scheduler=engine.scheduler, num_workers=engine.workers):
            yield None, None
    elif engine.scheduler == "processes":
        import multiprocessing

        # spawn: a forked child would inherit the parent's thread pools and locks mid-use.
        with concurrent.futures.ProcessPoolExecutor(
                engine.workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            yield pool, engine.threads_per_worker
    else:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError("engine.scheduler 'distributed' needs the dask.distributed package "
                             "(pip install 'dask[distributed]')") from None
        with contextlib.ExitStack() as stack:
            if engine.address is None:
                cluster = stack.enter_context(LocalCluster(
                    n_workers=engine.workers, threads_per_worker=1, dashboard_address=None))
                address = cluster.scheduler_address
            else:
                address = engine.address
            try:
                # connect timeout: dask config distributed.comm.timeouts.connect (30 s by default)
                client = stack.enter_context(Client(address, set_as_default=False))
            except OSError as error:
                raise InputError(f"engine.address: cannot reach the dask scheduler at {address}: {error}") from None
            yield client.get_executor(pure=False), engine.threads_per_worker


def run_chain(config: ChainConfig, *, progress: Progress | None = None, plan: RunPlan | None = None) -> RunReport:
    """Run a chain: parameter table (and fit), every scene, run report.

    Parameters
    ----------
    config : ChainConfig
    progress : callable, optional
        ``progress(event, info)`` (module docstring).
    plan : RunPlan, optional
        A plan made by :func:`plan_run` (made here otherwise).

    Returns
    -------
    RunReport
        Also written to ``plan.report`` (JSON). ``report.ok`` is False when a scene failed.

    Raises
    ------
    BrdfcorrError
        Before any scene runs: no inputs, a bad parameter table, a failed fit step, an unreachable
        cluster. Failures of single scenes do not raise; they are in the report.
    """
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    clock = time.perf_counter()
    plan = plan if plan is not None else plan_run(config)
    notify = progress or (lambda event, info: None)
    notify("plan", {"scenes": len(plan.scenes),
                    "to_run": sum(scene.action != "skip" for scene in plan.scenes)})

    tick = time.perf_counter()
    table, fit_report = build_table(plan, progress)
    timings = {"parameters": round(time.perf_counter() - tick, 3)}
    # Outputs made with another parameter table are not this run's results: redo them.
    scenes = tuple(_unless_stale(scene, table) for scene in plan.scenes)
    plan = dataclasses.replace(plan, scenes=scenes)
    to_run = [scene for scene in plan.scenes if scene.action != "skip"]
    report = RunReport(plan, table, fit=fit_report, started=started)
    plan.output_dir.mkdir(parents=True, exist_ok=True)

    previous = _previous_results(plan.report)
    for scene in plan.scenes:
        if scene.action == "skip":
            result = {"scene": scene.name, "image": str(scene.image), "status": "skipped",
                      "reason": scene.reason, "outputs": {k: str(v) for k, v in scene.outputs.items()}}
            earlier = previous.get(str(scene.image), {})
            for key in ("reference", "qa"):  # what the run that wrote the outputs found
                if key in earlier:
                    result[key] = earlier[key]
            report.scenes.append(result)
            notify("scene", result)
    tick = time.perf_counter()
    with _executor(config) as (executor, threads):
        if executor is None:
            for scene in to_run:
                result = process_scene(scene, table, config)
                report.scenes.append(result)
                notify("scene", result)
        else:
            futures = {executor.submit(process_scene, scene, table, config, threads=threads): scene
                       for scene in to_run}
            for future in concurrent.futures.as_completed(futures):
                scene = futures[future]
                try:
                    result = future.result()
                except Exception as error:  # noqa: BLE001 (the worker died: a crash, memory, a lost connection)
                    result = {"scene": scene.name, "image": str(scene.image), "status": "failed",
                              "error": f"worker failed: {type(error).__name__}: {error}",
                              "error_type": type(error).__name__}
                report.scenes.append(result)
                notify("scene", result)
    timings["scenes"] = round(time.perf_counter() - tick, 3)
    order = {str(scene.image): index for index, scene in enumerate(plan.scenes)}
    report.scenes.sort(key=lambda result: order.get(result["image"], len(order)))
    timings["total"] = round(time.perf_counter() - clock, 3)
    report.timings = timings
    with atomic_path(plan.report) as temporary:
        temporary.write_text(json.dumps(report.to_dict(), indent=2, default=_json_default))
    report.path = plan.report
    return report


def _unless_stale(scene: Scene, table: ParameterTable) -> Scene:
    """The scene, turned from ``skip`` to ``run`` if its corrected output was written with another
    parameter table (provenance tag ``brdf_parameter_table_content`` of
    :func:`brdfcorr.correct.correct_files`)."""
    if scene.action != "skip" or "corrected" not in scene.outputs:
        return scene
    import rasterio

    try:
        with rasterio.open(scene.outputs["corrected"]) as dataset:
            written = json.loads(dataset.tags().get("brdf_parameter_table_content", "null"))
    except (rasterio.errors.RasterioError, ValueError):
        written = None
    if written == json.loads(json.dumps(table.to_dict())):
        return scene
    return dataclasses.replace(scene, action="run", reason="outputs were made with another parameter table")


def _previous_results(path: Path) -> dict[str, dict]:
    """Scene results of an earlier report at ``path``, by image (empty if none or unreadable)."""
    try:
        scenes = json.loads(path.read_text())["scenes"]
        return {result["image"]: result for result in scenes if result.get("status") in ("ok", "skipped")}
    except (OSError, ValueError, KeyError, TypeError):
        return {}


def _json_default(value):
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serializable")
