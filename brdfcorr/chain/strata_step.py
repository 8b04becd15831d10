"""The strata step of a chain run (``steps.strata``): the class map of every scene derived from its
own image, NDVI strata as ``brdfcorr classes ndvi`` makes them, before the fit and the correction
use it (:func:`derive_strata`, called by :func:`brdfcorr.chain.run.run_chain`)."""

from __future__ import annotations

import contextlib
import dataclasses

from brdfcorr.chain.config import ChainConfig
from brdfcorr.chain.plan import RunPlan
from brdfcorr.chain.progress import ChunkProgress, Progress
from brdfcorr.chain.scenes import Scene
from brdfcorr.errors import BrdfcorrError
from brdfcorr.tasks.classmaps import NdviBins, ndvi_class_file

__all__ = ["derive_strata"]


def derive_strata(plan: RunPlan, progress: Progress | None = None) -> RunPlan:
    """The strata step: every scene to run gets its class map, the NDVI strata of its image
    (``steps.strata``, as ``brdfcorr classes ndvi``), written to its ``strata`` output, before the
    fit pools the scenes' maps. A scene whose map cannot be made turns to ``fail`` with the reason;
    the others go on. Returns the plan with those scenes (the plan itself without the step)."""
    config = plan.config
    if config.steps.strata is None:
        return plan
    engine = config.engine
    local = engine.scheduler in ("threads", "synchronous")  # else the run's process uses its own threads
    compute = {"scheduler": engine.scheduler if local else "threads", "num_workers": engine.local_threads}
    return dataclasses.replace(plan, scenes=tuple(
        _strata(scene, config, compute, progress) if scene.action == "run" else scene for scene in plan.scenes))


def _strata(scene: Scene, config: ChainConfig, compute: dict, progress: Progress | None) -> Scene:
    step, inputs = config.steps.strata, config.inputs
    bins = NdviBins(edges=step.edges, percentiles=step.percentiles, water_id=step.water_id, shadow_id=step.shadow_id)
    # Its own progress label: the scene's later passes (correct, assess) count from 0 again.
    chunks = ChunkProgress(f"{scene.name} strata", progress) if progress is not None else contextlib.nullcontext()
    try:
        with chunks:
            ndvi_class_file(scene.raster, scene.outputs["strata"], bins=bins, wavelengths=inputs.wavelengths,
                            **scene.scaling(inputs.scale, inputs.offset), chunks=config.engine.chunk,
                            overwrite=True, **compute)
    except Exception as error:  # noqa: BLE001 (isolation: a scene's failure must not stop the run)
        reason = str(error) if isinstance(error, BrdfcorrError) else f"{type(error).__name__}: {error}"
        return dataclasses.replace(scene, action="fail", reason=f"steps.strata: {reason}")
    return scene
