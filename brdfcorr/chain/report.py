"""The run report of a chain run: one result record per scene, the report document, its JSON file.

Every scene's result is made by :func:`scene_result` (corrected, failed, skipped, or lost with its
worker): a dict, as it goes to the progress callback and into the report's ``scenes``.
"""

from __future__ import annotations

import json
import platform
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import dask
import numpy as np
import rasterio
import rioxarray
import xarray

from brdfcorr import __version__
from brdfcorr.chain.plan import RunPlan
from brdfcorr.chain.resume import earlier_report, fingerprint_digest
from brdfcorr.chain.scenes import Scene
from brdfcorr.errors import BrdfcorrError
from brdfcorr.io.files import atomic_path
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.correct import too_few_corrected

__all__ = ["RunReport", "scene_result", "failed_for_share", "assessment_summary", "earlier_findings", "versions"]

#: What a scene's result keeps of its correction and assessment (and a resumed run copies from the
#: report of the run that wrote the outputs).
FINDINGS = ("reference", "qa", "topographic", "assess")


def scene_result(scene: Scene, status: str, *, reason: str = "", found: Mapping | None = None,
                 error: BaseException | None = None, worker_failed: bool = False,
                 seconds: dict | None = None) -> dict:
    """The result record of one scene.

    Parameters
    ----------
    scene : Scene
    status : {"ok", "failed", "skipped"}
    reason : str, optional
        Why a scene was skipped.
    found : mapping, optional
        What the steps found: ``reference`` (the geometry used), ``qa`` (pixel counts of
        :func:`brdfcorr.correction.qa_counts`), ``topographic`` (the terrain step's method and C fit)
        and ``assess`` (:func:`assessment_summary`).
    error : exception, optional
        Why the scene failed: ``error`` (the message, after the error type unless it is a
        :class:`~brdfcorr.errors.BrdfcorrError` of the scene) and ``error_type``.
    worker_failed : bool, default False
        The error is the worker's (a crash, memory, a lost connection), not the scene's.
    seconds : dict, optional
        Time per step [s] and ``total``.

    Returns
    -------
    dict
        ``scene``, ``image``, ``status``, ``reason`` (if given), ``outputs``, the ``found`` items,
        ``error`` and ``error_type`` (on failure), ``seconds`` (if given).
    """
    result = {"scene": scene.name, "image": str(scene.image), "status": status}
    if reason:
        result["reason"] = reason
    result["outputs"] = {key: str(path) for key, path in scene.outputs.items()}
    if scene.fingerprint:  # what a resumed run checks its outputs and their counts by (chain.resume)
        result["fingerprint"] = fingerprint_digest(scene)
    result.update(found or {})
    if error is not None:
        message = f"{type(error).__name__}: {error}"
        if worker_failed:
            message = f"worker failed: {message}"
        elif isinstance(error, BrdfcorrError):  # its message names the file and the key
            message = str(error)
        result["error"] = message
        result["error_type"] = type(error).__name__
    if seconds is not None:
        result["seconds"] = seconds
    return result


def uncorrected_classes(fit_report: Mapping | None) -> list[str]:
    """The classes a fit step left out of the table (its guard rails refused them and no fallback
    replaced them), as ``"4 (shingle): fewer than 50 samples"`` (empty without a fit step)."""
    classes = (fit_report or {}).get("classes") or []
    return [f"{entry['class_id']} ({entry['name']}): {'; '.join(entry.get('reasons') or []) or 'not fitted'}"
            for entry in classes if entry.get("status") == "uncorrected"]


#: The scene results whose QA counts are judged: those of scenes corrected now or by an earlier run.
_JUDGED = ("ok", "skipped")


def failed_for_uncorrected(result: dict, classes: list[str]) -> dict:
    """A scene result that is ``failed`` where the scene holds pixels of classes left uncorrected
    (``classes``: :func:`uncorrected_classes`; the QA count ``unknown_class`` says it holds pixels
    of classes absent from the table): a run whose scenes came out partly uncorrected did not
    do what it was asked (unless the chain allows it: ``steps.fit.allow_uncorrected``). A skipped
    scene is judged by the QA counts its earlier run found, as a fresh run would judge it."""
    if result.get("status") not in _JUDGED or not classes or not result.get("qa", {}).get("unknown_class"):
        return result
    return {**result, "status": "failed", "error_type": "UncorrectedClasses",
            "error": f"{result['qa']['unknown_class']} pixels of classes the fit left uncorrected: "
                     f"class {'; class '.join(classes)} (set steps.fit.allow_uncorrected: true if that is expected, "
                     "or steps.fit.fallback)"}


def failed_for_share(result: dict, min_share: float) -> dict:
    """A scene result that is ``failed`` where the correction touched less than ``min_share`` of the
    scene's valid pixels (QA counts: ``corrected`` over ``corrected + no_class + unknown_class``;
    nodata is not counted): a class map that does not match the table (an aligned land-cover map
    without a lookup corrects nothing) did not do what the run was asked, unless the chain says so
    (``steps.correct.min_corrected_share``, 0 for none). A skipped scene is judged by the QA counts
    its earlier run found (the share is no part of the fingerprint: a stricter one redoes nothing)."""
    qa = result.get("qa") or {}
    if result.get("status") not in _JUDGED or not too_few_corrected(qa, min_share):
        return result
    valid = sum(int(qa.get(key, 0)) for key in ("corrected", "no_class", "unknown_class"))
    found = (f"only {100 * qa['corrected'] / valid:.1f} % of the {valid} valid pixels were corrected "
             f"({qa.get('no_class', 0)} have no class, {qa.get('unknown_class', 0)} a class the table does not "
             "have)" if valid else f"no pixel was corrected: all {qa.get('nodata', 0)} pixels are nodata")
    return {**result, "status": "failed", "error_type": "TooFewCorrected",
            "error": f"{found}, under steps.correct.min_corrected_share {min_share:g}; check the class map "
                     "against the table's class ids and the inputs' nodata, or lower the key (0: any share) if that "
                     "is expected"}


def assessment_summary(report: Mapping) -> list[dict]:
    """Per class of an assessment report (:meth:`brdfcorr.tasks.assess.Assessment.report`): id,
    name, pixels, the median over bands of |relative slope| [%/10 deg] before and after the
    correction (None where no band has a finite slope), and how many bands' slopes lie within 2
    sigma of 0 before and after, of how many have a sigma (``bands_within_2_sigma``, the report's).

    The relative slope is the least-squares slope of reflectance against the signed view zenith,
    1000 b / mean R (:func:`brdfcorr.analysis.assess.assess_view_angles`): near 0 after a
    correction that took the view-angle signal out.
    """
    rows = []
    for entry in report["view_angles"]["classes"]:
        medians = {}
        for stage in ("before", "after"):
            slopes = np.abs(np.array(entry[stage]["relative_slope"], dtype=float))  # None (NaN in JSON) -> nan
            finite = slopes[np.isfinite(slopes)]
            medians[stage] = float(np.median(finite)) if finite.size else None
        rows.append({"id": entry["id"], "name": entry["name"], "pixels": entry["pixels"],
                     "median_abs_relative_slope_percent_per_10deg": medians,
                     "bands_within_2_sigma": entry["bands_within_2_sigma"]})
    return rows


def earlier_findings(report: Path) -> dict[str, dict]:
    """What an earlier run found for its completed scenes (:data:`FINDINGS`), by image, from its
    report at ``report`` (empty if there is none or it is unreadable)."""
    try:
        return {
            result["image"]: {key: result[key] for key in FINDINGS if key in result}
            for result in earlier_report(report)["scenes"] if result.get("status") in ("ok", "skipped")
        }
    except (KeyError, TypeError, AttributeError):
        return {}


@dataclass
class RunReport:
    """The outcome of :func:`~brdfcorr.chain.run.run_chain`; :meth:`to_dict` is what the
    report file holds."""

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
                "warnings": list(self.plan.warnings),
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

    def write(self, path: Path) -> None:
        """Write the report (JSON) to ``path``, atomically; sets :attr:`path`. A full disk or the
        file size limit is one :class:`~brdfcorr.errors.OutputError` (:func:`brdfcorr.io.files.atomic_path`),
        and nothing is left at ``path``."""
        with atomic_path(path) as temporary:
            temporary.write_text(json.dumps(self.to_dict(), indent=2, default=_json_default))
        self.path = path


def versions(distributed: bool = False) -> dict[str, str]:
    """Versions of brdfcorr and the libraries a run depends on."""
    found = {
        "brdfcorr": __version__, "python": platform.python_version(), "numpy": np.__version__,
        "xarray": xarray.__version__, "dask": dask.__version__, "rasterio": rasterio.__version__,
        "gdal": rasterio.__gdal_version__, "rioxarray": rioxarray.__version__,
    }
    if distributed:
        import distributed as dist  # an optional dependency (the distributed engine only)

        found["distributed"] = dist.__version__
    return found


def _json_default(value):
    if isinstance(value, (np.integer, np.floating)):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serializable")
