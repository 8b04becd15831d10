"""Leave one line out: a test of the correction on data its parameters never saw.

For N flight lines, :func:`leave_one_line_out` fits the parameters on N - 1 of them
(:func:`brdfcorr.fit.fit_classes`), corrects the held-out line with them
(:func:`brdfcorr.normalize`) and assesses it (:func:`brdfcorr.analysis.view_angles.assess_view_angles`,
and :func:`brdfcorr.analysis.overlap.assess_overlap` against the lines it overlaps).
:func:`leave_one_line_out_report` turns the results into a plain dict (valid JSON).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, NamedTuple

import dask
import dask.array as da
import numpy as np
import xarray as xr

from brdfcorr.analysis.overlap import _overlaps, assess_overlap, overlap_report
from brdfcorr.analysis.signed_view import check_signing
from brdfcorr.analysis.view_angles import ViewAngleOptions, assess_view_angles, view_angle_report
from brdfcorr.defaults import DEFAULT_LIMITS
from brdfcorr.errors import InputError

if TYPE_CHECKING:
    from brdfcorr.fit.prior import ShapePrior

__all__ = ["Line", "HeldOutLine", "HoldoutFit", "leave_one_line_out", "leave_one_line_out_report"]


class Line(NamedTuple):
    """One flight line in memory: reflectance (band, y, x) [1], class map (y, x) and the angles
    ``sza``, ``saa``, ``vza``, ``vaa`` (y, x) [deg] on its grid (georeferenced for overlaps);
    optionally a cluster layer (y, x) of integer ids for the slopes' 1-sigma
    (:func:`brdfcorr.analysis.view_angles.assess_view_angles`: detectors, acquisition days)."""

    name: str
    reflectance: xr.DataArray
    classes: xr.DataArray
    angles: Mapping[str, xr.DataArray]
    clusters: xr.DataArray | None = None


@dataclass
class HeldOutLine:
    """One line of :func:`leave_one_line_out`: assessed after a correction with parameters fitted
    on the other lines.

    Attributes
    ----------
    name : str
    table : ParameterTable
        The parameters fitted without this line.
    view : xarray.Dataset
        :func:`assess_view_angles` of the line before and after.
    overlaps : dict of str to xarray.Dataset
        :func:`assess_overlap` against each overlapping other line (both corrected with ``table``
        to ``reference``).
    fit_report : list of dict
        The fit's per-class report (:meth:`brdfcorr.fit.ClassFitResult.report`).
    reference : dict
        The reference geometry this line and the lines it overlaps were corrected to: ``sza``,
        ``vza`` [deg] as given (a ``"mean"`` sun zenith replaced by the mean over all the lines
        [deg]) and ``sza_from``, how its sun zenith was chosen (:func:`_common_reference`).
    """

    name: str
    table: Any
    view: xr.Dataset
    overlaps: dict[str, xr.Dataset] = field(default_factory=dict)
    fit_report: list = field(default_factory=list)
    reference: dict[str, object] = field(default_factory=dict)


@dataclass(frozen=True)
class HoldoutFit:
    """How :func:`leave_one_line_out` fits the parameters on the other lines and corrects the
    held-out line with them.

    Attributes
    ----------
    model : str, default "torrance_sparrow"
        Model fitted for every class (:func:`brdfcorr.fit.fit_classes`).
    class_models : mapping of int to str, optional
        The model of single classes, by class id.
    fixed : mapping of str to float, optional
        Shape parameters held fixed in the fits.
    max_samples : int, default 50000
        Pixels sampled per class over the training lines.
    seed : int, default 0
        Seed of the pixel sampler.
    reference : mapping, optional
        Reference geometry of the correction (:func:`brdfcorr.normalize`; default: the mean sun
        zenith, nadir view: ``{"sza": "mean", "vza": 0.0}``). A ``"mean"`` sun zenith is the mean
        over all the lines (of each line's scene mean), one sun for every line, so that an
        overlap compares two lines corrected to the same sun.
    limits : (float, float) or None, default DEFAULT_LIMITS
        Limits of the correction factor [-] (:data:`brdfcorr.defaults.DEFAULT_LIMITS`; None: none).
    prior : ShapePrior, optional
        A coefficient set's kernel shape as the prior of each fit (:class:`brdfcorr.fit.ClassModels`'
        ``prior``; None: the fits alone).
    default_names : mapping of int to str, optional
        Names of the classes that the view options' ``class_names`` do not name (the class maps'
        ``class_names`` tags): they name the fitted and the assessed classes, but describe what a
        map may hold, so unlike the given names they are not checked against the classes the
        training lines hold (:class:`brdfcorr.fit.ClassModels`' ``default_names``).
    """

    model: str = "torrance_sparrow"
    class_models: Mapping[int, str] | None = None
    fixed: Mapping[str, float] | None = None
    max_samples: int = 50_000
    seed: int = 0
    reference: Mapping[str, object] | None = None
    limits: tuple[float, float] | None = DEFAULT_LIMITS
    prior: ShapePrior | None = None
    default_names: Mapping[int, str] | None = None


def leave_one_line_out(
    lines: Sequence[Line], fit: HoldoutFit = HoldoutFit(), *,
    view_options: ViewAngleOptions = ViewAngleOptions(), overlap: bool = True,
) -> list[HeldOutLine]:
    """Fit on N − 1 lines, correct the held-out one, assess it: for each of N lines.

    Parameters
    ----------
    lines : sequence of Line
        At least 2 lines (angles by name ``sza``, ``saa``, ``vza``, ``vaa`` [deg]).
    fit : HoldoutFit
        The imagery fit, as for :func:`brdfcorr.fit.fit_classes` (its default guard rails; a
        class that fails them is left uncorrected), and the correction's reference geometry and
        limits (:func:`brdfcorr.normalize`).
    view_options : ViewAngleOptions
        The assessment of each held-out line (:func:`assess_view_angles`). Its ``class_names`` also
        name the classes of the fits (a name of a class that no training line holds is warned
        about, :class:`~brdfcorr.fit.classes.ClassFitWarning`; ``fit.default_names`` name the others
        without a warning), and its ``flip_view_azimuth`` (``vaa`` stored as seen from
        the sensor) applies to the fits and the corrections too.
    overlap : bool, default True
        Also compare the held-out line with every other line it overlaps (both corrected with the
        parameters fitted without it, to one reference geometry: a ``"mean"`` sun zenith is the
        mean of the lines' mean sun zeniths), :func:`assess_overlap`.

    Returns
    -------
    list of HeldOutLine
        One per line, in order.
    """
    from brdfcorr.correction import normalize
    from brdfcorr.fit import ClassModels, Sampling, fit_classes

    if len(lines) < 2:
        raise InputError(f"leave-one-line-out needs at least 2 lines, got {len(lines)}")
    for line in lines:  # before any fold's fit
        check_signing(view_options.by, line.angles["saa"], line.angles["vaa"])
    # The settings by the names the fit and the correction below take them.
    model, class_models, fixed, max_samples, seed = fit.model, fit.class_models, fit.fixed, fit.max_samples, fit.seed
    limits, names, flip_view_azimuth = fit.limits, view_options.class_names, view_options.flip_view_azimuth
    models = ClassModels(model, class_models=class_models, fixed=fixed, names=names, prior=fit.prior,
                         default_names=fit.default_names)
    if fit.default_names:  # the assessment names the classes as the fits do
        view_options = replace(view_options, class_names={**fit.default_names, **(names or {})})
    geometry, sza_from = _common_reference(lines, fit.reference)
    results = []
    for held, line in enumerate(lines):
        training = [other for index, other in enumerate(lines) if index != held]
        fitted = fit_classes([t.reflectance for t in training], [t.classes for t in training],
                             [xr.Dataset(dict(t.angles)) for t in training], models,
                             sampling=Sampling(max_samples=max_samples, seed=seed,
                                               flip_view_azimuth=flip_view_azimuth))

        def corrected(target: Line, table=fitted.table) -> xr.DataArray:
            return normalize(target.reflectance, target.classes, target.angles, table, geometry, limits=limits,
                             flip_view_azimuth=flip_view_azimuth).reflectance

        after = corrected(line)
        view = assess_view_angles(line.reflectance, after, line.classes, line.angles["vza"], line.angles["vaa"],
                                  line.angles["saa"], clusters=line.clusters, options=view_options)
        overlaps = _overlap_assessments(line, after, training, corrected) if overlap else {}
        reference = {**geometry, "sza_from": sza_from}
        results.append(HeldOutLine(line.name, fitted.table, view, overlaps, fitted.report(), reference))
    return results


def _overlap_assessments(line: Line, after: xr.DataArray, others: Sequence[Line],
                         corrected: Callable[[Line], xr.DataArray]) -> dict[str, xr.Dataset]:
    """:func:`assess_overlap` of ``line`` (``after``: corrected) against each of ``others`` it
    overlaps, corrected by ``corrected`` (the same parameters and reference geometry), by name."""
    return {other.name: assess_overlap(line.reflectance, after, other.reflectance, corrected(other))
            for other in others if _overlaps(line.reflectance, other.reflectance)}


def _common_reference(lines: Sequence[Line],
                      reference: Mapping[str, object] | None) -> tuple[dict[str, object], str]:
    """The reference geometry every line is corrected to (default ``{"sza": "mean", "vza": 0.0}``)
    and how its sun zenith was chosen. A ``"mean"`` sun zenith becomes the mean over the lines of
    each line's scene-mean sun zenith [deg] (:func:`brdfcorr.correction.reference.scene_mean_sza`),
    ``"mean of the lines"``: corrected each to its own scene mean, two lines under different suns
    would differ in their overlap by the BRDF between the two suns, not by the correction's error.
    Other sun zeniths are kept: a number [deg] (``"fixed"``), ``"observed"`` (each pixel's own sun)
    or ``"hls"`` (each line's)."""
    from brdfcorr.correction.reference import scene_mean_sza

    geometry = dict(reference) if reference is not None else {"sza": "mean", "vza": 0.0}
    sza = geometry.get("sza", "observed")
    if sza != "mean":
        return geometry, sza if isinstance(sza, str) else "fixed"
    layers = [line.angles["sza"].data for line in lines]
    means = dask.compute(*(scene_mean_sza(layer, da if isinstance(layer, da.Array) else np) for layer in layers))
    missing = [line.name for line, mean in zip(lines, means) if not np.isfinite(mean)]
    if missing:
        raise InputError(f"line {missing[0]}: no valid solar zenith for the mean sun zenith of the lines")
    return {**geometry, "sza": float(np.mean(means))}, "mean of the lines"


def leave_one_line_out_report(results: Sequence[HeldOutLine]) -> dict[str, object]:
    """:func:`leave_one_line_out` as a JSON-serialisable dict: per held-out line its view-angle
    report, the reference geometry it and the lines it overlaps were corrected to (``sza``,
    ``vza`` [deg], ``sza_from``), its overlap reports by other line, and the fit without it."""
    return {
        "kind": "leave-one-line-out",
        "lines": [{"held_out": result.name, "view_angles": view_angle_report(result.view),
                   "reference": dict(result.reference),
                   "overlaps": {name: overlap_report(data) for name, data in result.overlaps.items()},
                   "fit": result.fit_report} for result in results],
    }
