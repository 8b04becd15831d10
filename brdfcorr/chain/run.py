"""One chain run: sources -> fit? -> normalize -> sinks, for many scenes, with a run report.

:func:`~brdfcorr.chain.plan.plan_run` expands a :class:`~brdfcorr.chain.config.ChainConfig`
into scenes and decides what happens to each (``run``, ``skip``, ``fail``; :mod:`.plan`).
:func:`run_chain` follows that plan:

0. derives the class map of every scene to run where ``steps.strata`` says so: NDVI strata of its
   image (:func:`brdfcorr.tasks.classmaps.ndvi_class_file`), the class map of the steps below; a
   scene whose map cannot be made fails;
1. builds the parameter table: built-in materials, the table file, the ``fit`` step (from
   goniometer CSVs with :func:`brdfcorr.tasks.goniometer.fit_measurement_file` or from the imagery
   with :func:`brdfcorr.tasks.fit.fit_class_files`), merged in that order (later wins for a
   class id), with the strata's ``ndvi_interpolation`` block where the strata step asks for it;
2. normalizes every scene to run with :func:`brdfcorr.tasks.correct.correct_files` (lazy, chunked,
   atomic writes, QA counts; optionally the uncertainty raster and tilted surfaces,
   :class:`brdfcorr.tasks.correct.Terrain`), assesses the view-angle signal left in it
   (``steps.assess``: :func:`brdfcorr.tasks.assess.assess_files`, a JSON report and a figure)
   and writes a before/after quicklook (:func:`brdfcorr.chain.quicklook.write_quicklook`);
3. writes the run report (JSON; :mod:`.report`): inputs, parameter table and its sources,
   versions, timings, per-scene QA counts and errors.

A failing scene is recorded (message and error type) and the others go on. Before step 1 the
temporary files an interrupted earlier run left beside the run's outputs are removed
(:func:`brdfcorr.io.paths.remove_partials`); the plan has already checked that no output is an
input or another output, and each corrected output records the plan's fingerprint of its inputs
and settings (:func:`brdfcorr.chain.resume.scene_fingerprint`) for the next resume.

Execution engines (``engine.scheduler``):

``threads``       scenes one after another, each scene's chunks on ``workers`` threads (default:
                  those of ``brdfcorr correct``, :func:`brdfcorr.defaults.default_threads`)
``synchronous``   everything in the calling thread
``processes``     ``workers`` scenes at once in a process pool (``threads_per_worker`` each)
``distributed``   every scene spread chunk by chunk over all workers of a ``dask.distributed``
                  cluster (``address``, or a local cluster of ``workers`` processes with
                  ``threads_per_worker`` threads each), ``workers`` scenes in flight at once, so
                  the cluster also runs several scenes side by side; workers read the inputs and
                  write the outputs (each chunk under a :class:`distributed.Lock` of its file,
                  :mod:`brdfcorr.io.writer`), so they need the file system of both

The dask scheduler of a scene's chunks is passed to each computation (``scheduler``,
``num_workers`` of :func:`dask.compute`; the cluster's client for ``distributed``), never set
process-wide: scenes running side by side do not share a setting.

Nothing here prints: progress goes to a callback ``progress(event, info)`` with events ``"plan"``
(``{"scenes": n, "to_run": n_not_skipped}``), ``"fit"`` (``{"classes": [...]}``), ``"chunks"``
(``{"scene": name, "done": n, "total": n}``: the dask tasks of a scene's passes, from its first
(the checks of the angles and of the reflectance scale) to its last (the write, the assessment),
counted together, so that ``done`` only grows and ``total`` grows as each pass starts; with the
``threads`` and ``synchronous`` engines only, at the start of each pass, at most every
:data:`brdfcorr.chain.progress.CHUNK_EVENT_SECONDS` and at its end) and ``"scene"`` (the scene's result,
:func:`~brdfcorr.chain.report.scene_result`).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import os
import time
from collections.abc import Iterator, Mapping
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

try:  # advisory file locks (POSIX): one chain run per output directory
    import fcntl
except ImportError:  # pragma: no cover (Windows)
    fcntl = None  # type: ignore[assignment]

from brdfcorr._entry import entered
from brdfcorr.analysis.assess import ViewAngleOptions
from brdfcorr.chain.config import ChainConfig, EngineConfig, load_config
from brdfcorr.chain.plan import RunPlan, plan_run
from brdfcorr.chain.products import stacked_scenes
from brdfcorr.chain.progress import ChunkProgress, Progress
from brdfcorr.chain.quicklook import write_quicklook
from brdfcorr.chain.report import (
    RunReport,
    assessment_summary,
    earlier_findings,
    failed_for_share,
    failed_for_uncorrected,
    scene_result,
    uncorrected_classes,
    versions,
)
from brdfcorr.chain.resume import configured_table, reused_fit_report, with_strata_interpolation
from brdfcorr.chain.scenes import Scene
from brdfcorr.chain.strata_step import derive_strata
from brdfcorr.errors import InputError, OutputError
from brdfcorr.fit.measurements import MeasurementSelection
from brdfcorr.io import cluster
from brdfcorr.io.paths import remove_partials
from brdfcorr.io.scene import SceneSources
from brdfcorr.params import ParameterTable, merge_tables
from brdfcorr.plot.assess import write_assessment_figures
from brdfcorr.tasks.assess import assess_files, write_json
from brdfcorr.tasks.classmaps import class_preparation
from brdfcorr.tasks.correct import Terrain, correct_files
from brdfcorr.tasks.fit import SceneFiles, fit_class_files
from brdfcorr.tasks.goniometer import fit_measurement_file
from brdfcorr.tasks.pool import worker_processes
from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles

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
    "run_lock",
    "LOCK_NAME",
]

# ----------------------------------------------------------------------------------- parameters
def _scene_sources(scene: Scene, config: ChainConfig, kind: type[SceneSources] = SceneSources,
                   **extra) -> SceneSources:
    """The files of a planned scene as the tasks take them (a :class:`SceneSources`, or ``kind``
    with the ``extra`` fields), read as ``inputs`` says (scale, offset); a product's stack labelled
    with the product, as messages and the fitted table's record name it."""
    return kind(scene.raster, scene.classes, scene.angles, angles_kind=scene.angles_kind,
                angle_options=dict(scene.angle_options), **scene.scaling(config.inputs.scale, config.inputs.offset),
                label=str(scene.image) if scene.stack is not None else None, **extra)


def _scene_files(scene: Scene, config: ChainConfig) -> SceneFiles:
    inputs = config.inputs
    return _scene_sources(scene, config, SceneFiles, name=scene.name,  # type: ignore[return-value]
                          align_classes=inputs.align_classes, class_lookup=dict(inputs.class_lookup))


def _fit_imagery(plan: RunPlan) -> tuple[ParameterTable, dict]:
    config = plan.config
    step = config.steps.fit
    failed = [{"scene": s.name, "reason": s.reason} for s in plan.scenes if s.action == "fail"]
    candidates = [_scene_files(s, config) for s in plan.scenes if s.action != "fail"]
    reasons = "".join(f"; {s['scene']}: {s['reason']}" for s in failed)
    if not candidates:
        raise InputError(f"steps.fit: no scene could be opened for the imagery fit{reasons}")
    names = {class_id: name for class_id, name in config.parameters.materials.items()}
    try:
        fit = fit_class_files(candidates, **step.fit_settings(names, config.flips_view_azimuth),
                              chunks=config.engine.chunk,
                              wavelengths=config.inputs.wavelengths, skip_unreadable=True,
                              workers=_fit_workers(config.engine))
    except InputError as error:
        raise InputError(f"steps.fit: {error}{reasons}") from None
    report = fit.report()
    report["scenes_left_out"] = failed + report["scenes_left_out"]
    return fit.table, report


def _fit_workers(engine: EngineConfig) -> int:
    """The processes of the fit step's pool (the classes of an imagery fit, the candidates of a
    goniometer ``auto``): the engine's workers where it runs scenes in processes, else one."""
    return engine.workers if engine.scheduler == "processes" else 1


def _fit_goniometer(plan: RunPlan) -> tuple[ParameterTable, dict]:
    config = plan.config
    table, classes, notes = ParameterTable(), [], []
    for item in config.steps.fit.measurements:
        fit = fit_measurement_file(
            config.resolve(item.file), item.model, fixed=item.fixed, initial=item.initial,
            select=MeasurementSelection(item.min_phi, item.max_phi, item.max_zenith),
            workers=_fit_workers(config.engine),
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
    tables = [configured_table(config)]
    fit_report = None
    step = config.steps.fit
    if step is not None:
        if plan.reuses_fit:
            fitted = ParameterTable.load(plan.fit_output)
            fit_report = reused_fit_report(step.source, plan.fit_output, plan.report)
        else:
            fitted, fit_report = (_fit_imagery if step.source == "imagery" else _fit_goniometer)(plan)
            if not len(fitted) and not len(tables[0]) and config.steps.correct is not None:
                # Nothing written: an empty table would be reused by the next run of the same chain.
                left = "; ".join(uncorrected_classes(fit_report)) or "no class in the images"
                raise InputError(f"{config.source}: the fit step fitted no class ({left}); the run has no parameter "
                                 "to correct with (steps.fit.fallback gives such classes a built-in material)")
            plan.output_dir.mkdir(parents=True, exist_ok=True)
            fitted.save(plan.fit_output)
            fit_report.update(output=str(plan.fit_output), fingerprint=plan.fit_fingerprint)
        tables.append(fitted)
        if progress is not None:
            progress("fit", {"classes": list(fitted.class_ids), **fit_report})
    table = merge_tables(tables)
    if not len(table) and config.steps.correct is not None:
        raise InputError(f"{config.source}: the parameter table of the run has no class")
    return with_strata_interpolation(table, config), fit_report


# --------------------------------------------------------------------------------------- scenes
def process_scene(scene: Scene, table: ParameterTable, config: ChainConfig, *, scheduler: object = None,
                  threads: int | None = None, progress: Progress | None = None) -> dict:
    """Correct one scene, assess it and write its outputs; never raises: failures go into the result.

    Parameters
    ----------
    scene : Scene
    table : ParameterTable
    config : ChainConfig
    scheduler : {"threads", "synchronous"} or distributed.Client, optional
        dask scheduler of the scene's computations (a cluster's client spreads its chunks over
        the cluster); ``"threads"`` when ``threads`` is given, else dask's default (the caller's
        configuration).
    threads : int, optional
        Number of threads of the ``"threads"`` scheduler (inside process workers, the engine's
        ``threads_per_worker``).
    progress : callable, optional
        ``progress("chunks", {...})`` from the scene's first pass to its last (:class:`ChunkProgress`,
        active while the scene's steps run; dask's local schedulers only, not a cluster's).

    Returns
    -------
    dict
        :func:`~brdfcorr.chain.report.scene_result`: ``scene``, ``status`` (``ok``,
        ``failed``), ``outputs``, ``qa`` (pixel counts of :func:`brdfcorr.correction.qa_counts`),
        ``reference``, ``topographic`` (with ``steps.correct.terrain``), ``assess`` (with
        ``steps.assess``, :func:`~brdfcorr.chain.report.assessment_summary`), ``seconds`` (per
        step) and, on failure, ``error`` and ``error_type``.
    """
    scheduler = scheduler or ("threads" if threads else None)
    compute: dict[str, Any] = {"scheduler": scheduler, "num_workers": threads}
    found: dict = {}
    seconds: dict = {}
    failure = None
    start = time.perf_counter()
    steps = config.steps
    try:
        if scene.action == "fail":
            raise InputError(scene.reason)
        for path in scene.outputs.values():
            path.parent.mkdir(parents=True, exist_ok=True)
        if steps.correct is not None:
            _remove_derived(scene)
        # Active for every pass of the scene, from the first (the checks before the write), as for `correct`.
        # Messages name chain keys (brdfcorr._entry), also in process workers.
        chunks = ChunkProgress(scene.name, progress) if progress is not None else contextlib.nullcontext()
        with entered("chain"), chunks:
            for name, run in (("correct", lambda: _correct(scene, table, config, **compute)),
                              ("assess", lambda: _assess(scene, table, config, **compute)),
                              ("quicklook", lambda: _quicklook(scene, config, table))):
                if getattr(steps, name) is None:
                    continue
                tick = time.perf_counter()
                found.update(run())
                seconds[name] = round(time.perf_counter() - tick, 3)
    except Exception as error:  # noqa: BLE001 (isolation: a scene's failure must not stop the run)
        failure = error
    seconds["total"] = round(time.perf_counter() - start, 3)
    return scene_result(scene, "ok" if failure is None else "failed", found=found, error=failure, seconds=seconds)


#: A scene's outputs made from its corrected image after that is in place (the assessment and
#: the quicklook): removed before the scene is corrected again.
DERIVED_OUTPUTS = ("assess", "assess_profiles", "quicklook")


def _remove_derived(scene: Scene) -> None:
    """Remove the :data:`DERIVED_OUTPUTS` of an earlier run of a scene about to be corrected again:
    a run killed after the new corrected image was renamed into place, before they were redone,
    then leaves them missing (a resumed run redoes the scene) instead of stale beside a corrected
    image whose fingerprint says the scene is complete."""
    for key in DERIVED_OUTPUTS:
        path = scene.outputs.get(key)
        if path is not None:
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


def _terrain(scene: Scene, config: ChainConfig) -> Terrain | None:
    step = config.steps.correct.terrain
    if step is None:
        return None
    return Terrain(slope_aspect=scene.slope_aspect, dem=scene.dem, topographic=step.topographic,
                   brdf_frame=step.brdf_frame)


def _correct(scene: Scene, table: ParameterTable, config: ChainConfig, *, scheduler,
             num_workers: int | None) -> dict:
    """The correct step; returns what it found: ``reference``, ``qa`` and ``topographic``."""
    step, outputs = config.steps.correct, config.outputs
    inputs = config.inputs
    sources = _scene_sources(scene, config, wavelengths=inputs.wavelengths)
    files = OutputFiles(
        scene.outputs["corrected"], qa=scene.outputs.get("qa"), uncertainty=scene.outputs.get("uncertainty"),
        format=outputs.format, interleave=outputs.interleave or "bsq", compress=outputs.compress, cog=outputs.cog,
        fingerprint=scene.fingerprint or None,  # what a resumed run compares (brdfcorr.chain.resume)
    )
    result = correct_files(CorrectionRequest(
        sources, table, files, reference=config.reference, limits=step.limits, extrapolate=step.extrapolate,
        unknown=step.unknown, flip_view_azimuth=config.flips_view_azimuth, terrain=_terrain(scene, config),
        factor_at=step.factor_at,
        align_classes=inputs.align_classes, class_lookup=dict(inputs.class_lookup),
        engine=Engine(chunks=config.engine.chunk, scheduler=scheduler, num_workers=num_workers),
        table_source=config.source, reads=scene.product_files,  # a product's files: never overwritten
    ))
    found: dict[str, object] = {"reference": result.reference.describe()}
    if result.notes:  # most pixels left uncorrected, an uncertainty without errors: said in the report too
        found["notes"] = list(result.notes)
    if result.topographic is not None:
        found["topographic"] = result.topographic.as_dict()
    found["qa"] = dict(result.counts)
    return found


def _assess(scene: Scene, table: ParameterTable, config: ChainConfig, *, scheduler, num_workers: int | None) -> dict:
    """The assess step: the JSON report and the profile figure; returns ``assess``, the per-class
    summary (:func:`~brdfcorr.chain.report.assessment_summary`)."""
    step, inputs = config.steps.assess, config.inputs
    sources = _scene_sources(scene, config)
    view_options = ViewAngleOptions(
        by=step.sign_by, heading=step.heading, class_names={entry.id: entry.name for entry in table.classes},
        bin_width=step.bin_width, min_vza=step.min_vza, flip_view_azimuth=config.flips_view_azimuth,
        block_size=step.block_size,
    )
    clusters = None if scene.clusters is None else (scene.clusters, step.cluster_band)
    assessment = assess_files(
        sources, scene.outputs["corrected"], view_options=view_options, align_classes=inputs.align_classes,
        class_lookup=dict(inputs.class_lookup), clusters=clusters,
        engine=Engine(chunks=config.engine.chunk, scheduler=scheduler, num_workers=num_workers),
    )
    report = assessment.report()
    write_json(report, scene.outputs["assess"])
    write_assessment_figures(assessment, scene.outputs["assess_profiles"].parent, prefix=f"{scene.name}_assess",
                             title=scene.name)
    return {"assess": assessment_summary(report)}


def _quicklook(scene: Scene, config: ChainConfig, table: ParameterTable) -> dict:
    step = config.steps.quicklook
    write_quicklook(
        scene.raster, scene.outputs["corrected"], scene.outputs["quicklook"], classes=scene.classes,
        bands=step.bands, percentiles=step.percentiles, max_size=step.max_size, title=scene.name,
        class_names={entry.id: entry.name for entry in table.classes},
        prepare_classes=class_preparation(config.inputs.align_classes, config.inputs.class_lookup),
    )
    return {}


# -------------------------------------------------------------------------------------- engines
@contextlib.contextmanager
def _executor(engine: EngineConfig) -> Iterator[tuple[concurrent.futures.Executor | None, dict]]:
    """(executor, compute): the executor of scene tasks (None: run them inline) and the keyword
    arguments of :func:`process_scene` naming the dask scheduler of a scene's chunks."""
    if engine.scheduler in ("threads", "synchronous"):
        yield None, {"scheduler": engine.scheduler, "threads": engine.local_threads}
    elif engine.scheduler == "processes":
        with worker_processes(engine.workers, (__name__,)) as pool:
            yield pool, {"scheduler": "threads", "threads": engine.threads_per_worker}
    else:
        # Scenes are driven from threads here; their chunks run on every worker of the cluster.
        with cluster.connect_cluster(engine.address, workers=engine.workers, setting="engine.address",
                                     threads_per_worker=engine.threads_per_worker) as client, \
                concurrent.futures.ThreadPoolExecutor(engine.workers) as scenes:
            yield scenes, {"scheduler": client}


#: The lock file of a chain run, in its output directory; it holds the running process's id.
LOCK_NAME = ".brdfcorr-run.lock"
_LOCK_ATTEMPTS = 5


@contextlib.contextmanager
def run_lock(directory: Path) -> Iterator[Path]:
    """Hold ``directory`` (a chain's output directory, created if absent) for this run.

    Two runs of one chain at once would delete each other's temporary files (the clean-up of an
    interrupted run) and replace each other's outputs and report. The lock is an advisory
    ``flock`` on :data:`LOCK_NAME` in ``directory``, which holds the holder's process id: a second
    run is refused while the first lives; the lock of a run that died (kill -9) is released by the
    system, and the next run takes it over. Removed when the run ends, with the directories made
    for it if they are still empty (a run refused before writing leaves nothing). Without ``fcntl``
    (Windows) runs are not locked.

    Raises
    ------
    OutputError
        Another process holds the lock (named with its pid).
    """
    directory = Path(directory)
    made = [folder for folder in (directory, *directory.parents) if not folder.exists()]
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(f"cannot create the output directory {directory}: {error.strerror or error}") from None
    path = directory / LOCK_NAME
    descriptor = _take_lock(path) if fcntl is not None else None
    try:
        if descriptor is not None:
            os.ftruncate(descriptor, 0)
            os.write(descriptor, f"{os.getpid()}\n".encode())
        yield path
    finally:
        if descriptor is not None:
            with contextlib.suppress(OSError):
                os.unlink(path)
            os.close(descriptor)
        for folder in made:  # deepest first; a folder with files in it stays
            with contextlib.suppress(OSError):
                folder.rmdir()


def _take_lock(path: Path) -> int:
    """An open descriptor of ``path`` holding its ``flock``; the file still at ``path`` (not one
    that the previous holder removed between our open and our lock)."""
    for _ in range(_LOCK_ATTEMPTS):
        try:
            descriptor = os.open(path, os.O_RDWR | os.O_CREAT | getattr(os, "O_CLOEXEC", 0), 0o666)
        except OSError as error:
            raise OutputError(f"cannot create the lock file {path}: {error.strerror or error}") from None
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(descriptor, 64).decode(errors="replace").strip() or "unknown"
            os.close(descriptor)
            raise OutputError(f"another brdfcorr run (pid {holder}) is writing to {path.parent} (lock file {path}); "
                              "wait for it to end: two runs of one chain would replace each other's files") from None
        try:
            if os.stat(path).st_ino == os.fstat(descriptor).st_ino:
                return descriptor
        except FileNotFoundError:
            pass
        os.close(descriptor)  # the holder removed the file as we locked it: lock the new one
    raise OutputError(f"cannot take the lock file {path}: it keeps being replaced by another run")


def _run_scenes(scenes: list[Scene], table: ParameterTable, config: ChainConfig,
                progress: Progress | None = None) -> Iterator[dict]:
    """The results of the scenes, as they finish, on the config's engine; ``progress`` hears the
    chunks of scenes run inline (``threads``, ``synchronous``)."""
    with _executor(config.engine) as (executor, compute):
        if executor is None:
            for scene in scenes:
                yield process_scene(scene, table, config, progress=progress, **compute)
            return
        futures = {executor.submit(process_scene, scene, table, config, **compute): scene for scene in scenes}
        for future in concurrent.futures.as_completed(futures):
            try:
                result = future.result()
            except Exception as error:  # noqa: BLE001 (the worker died: a crash, memory, a lost connection)
                result = scene_result(futures[future], "failed", error=error, worker_failed=True)
            yield result


# -------------------------------------------------------------------------------------------- run
def run_chain(config: ChainConfig | str | os.PathLike, *, overrides: Mapping[str, object] | None = None,
              progress: Progress | None = None, plan: RunPlan | None = None) -> RunReport:
    """Run a chain: parameter table (and fit), every scene, run report (``brdfcorr run``;
    ``brdfcorr.run_chain``).

    Parameters
    ----------
    config : path-like or ChainConfig
        The chain config file (YAML; relative paths are relative to it), or a config loaded with
        :func:`brdfcorr.chain.config.load_config`.
    overrides : mapping of str to object, optional
        Dotted keys to replace (``{"engine.workers": 2}``), as ``brdfcorr run --set``; only with a
        path (pass them to ``load_config`` otherwise).
    progress : callable, optional
        ``progress(event, info)`` (module docstring).
    plan : RunPlan, optional
        A plan made by :func:`plan_run` (made here otherwise); the run does what it says for each
        scene.

    Returns
    -------
    RunReport
        Also written to ``plan.report`` (JSON). ``report.ok`` is False when a scene failed.

    Raises
    ------
    TypeError
        ``overrides`` with a loaded config.
    BrdfcorrError
        Before any scene runs: a bad config, no inputs, a bad parameter table, a failed fit step, an
        unreachable cluster, another run writing to the output directory (:func:`run_lock`). Failures
        of single scenes do not raise; they are in the report. A report that cannot be written (a full
        disk) is an :class:`~brdfcorr.errors.OutputError`.
    """
    if isinstance(config, ChainConfig):
        if overrides:
            raise TypeError("overrides apply to a config file; give them to load_config for a loaded config")
    else:
        config = load_config(config, overrides)
    started = datetime.now(timezone.utc).isoformat(timespec="seconds")
    clock = time.perf_counter()
    with entered("chain"):  # messages name chain keys (brdfcorr._entry)
        plan = plan if plan is not None else plan_run(config)
    # Product scenes read their bands stacked in a scratch folder, removed when the run ends.
    with run_lock(plan.output_dir), entered("chain"), \
            stacked_scenes(plan.scenes, chunks=config.engine.chunk) as scenes:
        return _run_plan(dataclasses.replace(plan, scenes=scenes), progress, started, clock)


def _run_plan(plan: RunPlan, progress: Progress | None, started: str, clock: float) -> RunReport:
    """:func:`run_chain` once the output directory is this run's (:func:`run_lock`)."""
    config = plan.config
    notify = progress or (lambda event, info: None)
    notify("plan", {"scenes": len(plan.scenes), "to_run": sum(scene.action != "skip" for scene in plan.scenes)})
    for target in plan.files_written():  # temporary files an interrupted earlier run left beside them
        remove_partials(target)

    tick = time.perf_counter()
    plan = derive_strata(plan, progress)
    timings = {"strata": round(time.perf_counter() - tick, 3)} if config.steps.strata is not None else {}
    tick = time.perf_counter()
    table, fit_report = build_table(plan, progress)
    timings["parameters"] = round(time.perf_counter() - tick, 3)
    report = RunReport(plan, table, fit=fit_report, started=started)
    plan.output_dir.mkdir(parents=True, exist_ok=True)

    step = config.steps.fit
    left_uncorrected = [] if step is None or getattr(step, "allow_uncorrected", True) else \
        uncorrected_classes(fit_report)

    def judged(result: dict) -> dict:  # a scene's QA counts against the run's settings
        result = failed_for_uncorrected(result, left_uncorrected)
        if config.steps.correct is not None:
            result = failed_for_share(result, config.steps.correct.min_corrected_share)
        return result

    earlier = earlier_findings(plan.report)  # what the runs that wrote the skipped outputs found
    for scene in plan.scenes:
        if scene.action == "skip":
            report.scenes.append(judged(scene_result(scene, "skipped", reason=scene.reason,
                                                     found=earlier.get(str(scene.image)))))
            notify("scene", report.scenes[-1])
    tick = time.perf_counter()
    for result in _run_scenes([scene for scene in plan.scenes if scene.action != "skip"], table, config, progress):
        report.scenes.append(judged(result))
        notify("scene", report.scenes[-1])
    timings["scenes"] = round(time.perf_counter() - tick, 3)
    order = {str(scene.image): index for index, scene in enumerate(plan.scenes)}
    report.scenes.sort(key=lambda result: order.get(result["image"], len(order)))
    timings["total"] = round(time.perf_counter() - clock, 3)
    report.timings = timings
    report.write(plan.report)
    return report
