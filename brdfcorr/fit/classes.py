"""Fit per-class, per-band BRDF model parameters from the imagery itself, with guard rails.

Every class (roof tile, concrete, grass, ...) is seen under many sun/view geometries across a wide
field-of-view line, overlapping lines or revisits. :func:`fit_classes` pools each class's valid
pixels (:mod:`brdfcorr.fit.sampling`), fits a registered surface model to them, one shape per
class with intensity terms per band (:mod:`brdfcorr.fit.solver`), and checks each fit against
:class:`GuardRails` before it goes into the parameter table: enough samples, a spread of view
zeniths, a well-conditioned design, a model that explains the angular signal (median R^2), and
shape parameters inside their search ranges. A class that fails is left uncorrected or gets a
built-in material or coefficient set (its fallback); a class that fails or fits poorly is also
fitted with the other surface models, and one that explains clearly more is suggested in its report
(:attr:`ClassFit.better_model`).

Bad bands (water vapour, :data:`WATER_VAPOUR_BANDS`, or ranges given) are left out of the fit: the
table's classes list them as ``bad_bands`` (no parameters there), and the correction passes them
through uncorrected with the QA flag ``band_uncorrected``.

Imagery holds reflectance factors R (0-1, "BRF"/"HDRF"); brdfcorr's models are BRDFs in sr^-1.
The fit uses f = R / pi (a Lambertian surface of reflectance R has BRDF R / pi), so the intensity
parameters in the resulting table are in sr^-1 like the goniometer fits of paper 003.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from brdfcorr.defaults import AUTO_MODEL, ERROR_CLUSTERS
from brdfcorr.errors import BrdfcorrWarning, FitError, InputError, ParameterError
from brdfcorr.fit.class_fit import ClassFit, _finite_median
from brdfcorr.fit.entries import class_entry, record_source
from brdfcorr.fit.prior import KERNEL_WEIGHTS, PRIOR_MODEL, ShapePrior, prior_ratios, shape_posterior
from brdfcorr.fit.quality import fit_quality
from brdfcorr.fit.sampling import ClassSamples, sample_classes, scene_lists
from brdfcorr.fit.selection import (
    IMAGERY_CANDIDATES,
    SELECT_GRID,
    ModelChoice,
    check_fixed,
    choose_class_model,
    fixed_for,
)
from brdfcorr.fit.settings import (
    DEFAULT_MODEL,
    WATER_VAPOUR_BANDS,
    ClassModels,
    GuardRails,
    Sampling,
    fallback_entry,
)
from brdfcorr.fit.shapes import DEFAULT_FIXED, SEARCH_RANGES, intensity_terms, search_range
from brdfcorr.fit.solver import GRID_POINTS, LEVEL_TOLERANCE, MAX_LEVEL_ITERATIONS, fit_class_samples
from brdfcorr.fit.within import Levels
from brdfcorr.io.wavelengths import with_wavelengths
from brdfcorr.models import REGISTRY, Model, get_model
from brdfcorr.params import ParameterTable
from brdfcorr.params.bands import in_ranges

__all__ = [
    "ClassFitResult",
    "ClassSamples",
    "fit_classes",
    "sample_classes",
    "fit_one_class",
    "GuardRails",
    "ClassModels",
    "Sampling",
    "ClassFit",
    "ClassFitWarning",
    "intensity_terms",
    "fit_class_samples",
    "DEFAULT_FIXED",
    "SEARCH_RANGES",
    "WATER_VAPOUR_BANDS",
]

#: A fitted class whose median R^2 is below this is "poor": the other models are tried as well.
POOR_R2 = 0.5
#: Another model is suggested when its median R^2 exceeds the class model's by at least
#: ``BETTER_GAIN`` and is at least ``BETTER_FACTOR`` times it.
BETTER_GAIN = 0.1
BETTER_FACTOR = 2.0
#: The cost of trying the other models is bounded: ``SUGGEST_GRID`` grid points per shape
#: parameter, on the subsample of the held-out choice (:data:`brdfcorr.fit.selection.SELECT_SAMPLES`).
SUGGEST_GRID = 5


class ClassFitWarning(BrdfcorrWarning):
    """A class of an imagery fit needs a look: it failed a guard rail and fell back to a built-in
    material or to no correction, its free levels did not converge, or the class settings name
    classes that the fit does not have."""


def _warn(report: ClassFit, note: str) -> None:
    """``note`` in the class's notes, and a :class:`ClassFitWarning` naming the class."""
    report.notes.append(note)
    warnings.warn(f"class {report.class_id} ({report.name}): {note}", ClassFitWarning, stacklevel=3)


def _spread(values: np.ndarray) -> float:
    """5th-95th percentile range [deg]."""
    if values.size == 0:
        return 0.0
    low, high = np.percentile(values, [5, 95])
    return float(high - low)


def _angular(model: Model) -> bool:
    """Whether the model can vary with the geometry (Lambertian cannot: its R^2 is 0 by construction)."""
    return len(model.linear) > 1 or bool(model.shape_names)


def _within_spread(samples: ClassSamples, scenes: bool = False) -> float:
    """How differently the groups of free levels were seen [deg]: twice the 95th percentile of
    each sample's distance from its group's mean geometry, in (sun zenith, view zenith x cos and
    x sin of the relative azimuth), the polar plot of the view about the sun's azimuth. Two lines
    seeing a pixel at 20 deg from opposite sides give 40 deg; the pixels of a patch of one flight
    line, about their view zenith step. ``scenes``: what is left once each scene's mean is taken
    out as well (the two-way within geometry, :meth:`Levels.demean`)."""
    if samples.group is None or np.size(samples.theta_i) == 0:
        return 0.0
    levels = Levels.from_labels(samples.group, samples.scene if scenes else None)
    azimuth = np.radians(samples.phi)
    geometry = np.column_stack([samples.theta_i, samples.theta_r * np.cos(azimuth), samples.theta_r * np.sin(azimuth)])
    distance = np.linalg.norm(levels.demean(geometry), axis=1)[levels.counts[0][levels.factors[0]] >= 2]
    return 2.0 * float(np.percentile(distance, 95)) if distance.size else 0.0


def _sample_reasons(report: ClassFit, guard: GuardRails) -> list[str]:
    reasons = []
    if report.n_samples < guard.min_samples:
        reasons.append(f"{report.n_samples} samples < {guard.min_samples}")
    if report.vza_spread < guard.min_vza_spread:
        what = "view zenith spread" if report.levels == "pooled" else f"geometry spread within each {report.levels}"
        reasons.append(f"{what} {guard.spread_short(report.vza_spread)}")
    return reasons


def _fit_reasons(report: ClassFit, model: Model, at_edge: Sequence[str], guard: GuardRails) -> list[str]:
    """Why a fit fails its guard rails; poorly determined parameters of a good fit go to notes."""
    reasons = []
    if report.condition > guard.max_condition:
        reasons.append(
            f"ill-conditioned (condition {report.condition:.3g} > {guard.max_condition:g}): "
            f"the geometry does not separate the terms {', '.join(model.linear)}"
        )
    angular = report.median_angular_r2
    if _angular(model) and math.isnan(angular):
        reasons.append("no angular signal stands out of the samples' scatter within geometry bins (angular R^2 "
                       f"undefined): nothing for {model.name} to follow")
    elif _angular(model) and not angular >= guard.min_r2:
        reasons.append(f"median angular R^2 {angular:.3f} < {guard.min_r2:g}: "
                       f"{model.name} explains almost none of the angular signal")
    for name in at_edge:
        low, high, _ = search_range(model, name)
        where = f"{name} = {report.params[name][0]:.4g} at the edge of its search range ({low:g} to {high:g})"
        if angular >= POOR_R2:
            report.notes.append(f"{where}: poorly determined (the angular fit is good: R^2 {angular:.3f})")
        else:
            reasons.append(f"{where}: the data do not constrain it, or its optimum lies outside")
    for parameter in model.parameters:  # a table holds only values its model allows
        try:
            parameter.check(report.params.get(parameter.name, ()), model.name)
        except ParameterError as error:
            reasons.append(f"fitted {error}: the data do not determine it")
    return reasons


def _apply_prior(report: ClassFit, prior: ShapePrior, ratios: np.ndarray, samples: ClassSamples,
                 levels: Levels | None) -> None:
    """The fitted RTLSR weights, covariance and errors of ``report`` replaced by their posterior
    under ``prior`` (:func:`brdfcorr.fit.prior.shape_posterior`), and its R^2, angular R^2, RMS
    and chi^2/dof by the posterior's on ``samples`` (within the groups of the fit's free
    ``levels``, as the fit judged its own): the guard rails judge the weights delivered."""
    weights = np.column_stack([report.params[name] for name in KERNEL_WEIGHTS])
    posterior, covariance = shape_posterior(weights, report.covariance, ratios, prior.spread)
    report.params = {**report.params, **{name: posterior[:, j] for j, name in enumerate(KERNEL_WEIGHTS)}}
    report.errors = {**report.errors, **{name: np.sqrt(covariance[:, j, j]) for j, name in enumerate(KERNEL_WEIGHTS)}}
    report.covariance, report.prior = covariance, prior.label
    quality = fit_quality(PRIOR_MODEL, samples.theta_i, samples.theta_r, samples.phi, samples.brdf, posterior.T,
                          levels=levels)
    report.r2, report.rmse, report.angular_r2, report.chi2_dof = (
        quality[name] for name in ("r2", "rmse", "angular_r2", "chi2_dof"))


def _suggest_model(report: ClassFit, model: Model, samples: ClassSamples) -> None:
    """Record another surface model that predicts the class's held-out blocks clearly better than
    its own: the choice by held-out error (:func:`brdfcorr.fit.selection.choose_class_model`) among
    the class's model and :data:`~brdfcorr.fit.selection.IMAGERY_CANDIDATES`, when its held-out
    median R^2 is higher by :data:`BETTER_GAIN` and at least :data:`BETTER_FACTOR` times as high.
    Out of sample, a model with more terms wins only where the data show them."""
    candidates = tuple(dict.fromkeys((model.name, *IMAGERY_CANDIDATES)))
    try:
        choice = choose_class_model(samples, candidates=candidates, grid_points=SUGGEST_GRID)
    except FitError:
        return  # one spatial block: nothing held out to judge by
    if choice.chosen == model.name:
        return
    own = choice.score_of(model.name).heldout_r2
    own = own if math.isfinite(own) else 0.0
    better = choice.score_of(choice.chosen).heldout_r2
    if better >= own + BETTER_GAIN and better >= BETTER_FACTOR * own:
        report.better_model, report.better_r2 = choice.chosen, better


def fit_one_class(class_id: int, name: str, model: str | Model, samples: ClassSamples, *,
                  fixed: Mapping[str, float] | None = None, guard: GuardRails = GuardRails(),
                  fallback: str | None = None, grid_points: int = GRID_POINTS,
                  prior: tuple[ShapePrior, np.ndarray] | None = None, pool_if_alike: bool = False) -> ClassFit:
    """Fit one class's samples and apply the guard rails (see :func:`fit_class_samples`).

    A class that fails a guard rail, or fits poorly (median R^2 < :data:`POOR_R2`), is also fitted with
    the other surface models that can be fitted from imagery, on a subsample; one that explains clearly
    more is recorded in :attr:`ClassFit.better_model`.

    Parameters
    ----------
    class_id, name : int, str
        Class id and name.
    model : str or Model
        Surface model with intensity terms (:func:`intensity_terms`), or ``"auto"``: the candidate with
        the lowest held-out error over spatial blocks (:func:`brdfcorr.fit.selection.choose_class_model`;
        its scores are the report's ``model_choice``).
    samples : ClassSamples
        The class's samples: sun zenith, view zenith and relative azimuth [deg], BRDF per band [sr^-1],
        shape (N, B), and optionally the spatial block of each sample (``block``), over which the errors
        are cluster-robust (None: every sample is its own cluster).
    fixed : mapping of str to float, optional
        Shape parameters held fixed (default k = 0.25 for the Torrance-Sparrow models).
    guard : GuardRails
        Minimum requirements for the fit to be used.
    fallback : str, optional
        Built-in material or coefficient set used when the fit fails its guard rails
        (:func:`brdfcorr.fit.settings.fallback_entry`; None: left uncorrected).
    grid_points : int, default :data:`brdfcorr.fit.solver.GRID_POINTS`
        Coarse-grid points per free shape parameter.
    prior : (ShapePrior, ndarray), optional
        A shape prior and its ratios f_vol/f_iso, f_geo/f_iso per band (n_bands, 2;
        :func:`brdfcorr.fit.prior.prior_ratios`) for a ``ross_thick_li_sparse`` class: its weights
        become the posterior's (:func:`brdfcorr.fit.prior.shape_posterior`), and the condition-number
        rail does not apply. Ignored for other models.
    pool_if_alike : bool, default False
        For samples with free levels (``samples.group``) chosen by ``levels="auto"``: where the views of
        each group differ by less than the guard rail's spread (:func:`_within_spread`, e.g. dates from
        one orbit at one time of day), fit them pooled instead, with a note.

    Returns
    -------
    ClassFit
    """
    notes: list[str] = []
    samples, within = _pooled_if_alike(samples.finite(notes), guard, pool_if_alike, notes)
    model, fixed, choice = _class_model(model, samples, fixed, grid_points, notes)
    report = ClassFit(
        class_id=class_id, name=name, model=model.name, n_samples=int(np.size(samples.theta_i)),
        vza_spread=_spread(np.asarray(samples.theta_r)) if within is None else within,
        phi_spread=_spread(np.asarray(samples.phi)), fallback=fallback, notes=notes, model_choice=choice,
        levels=samples.levels,
    )
    # A band empty at every pixel sampled leaves no sample: that is the reason, not the count.
    report.reasons = [samples.empty_reason] if samples.empty_reason else _sample_reasons(report, guard)
    if report.n_samples >= max(len(model.parameters) + 1, 3):
        _fit_samples(report, model, samples, fixed, grid_points, prior, guard)
    if report.reasons:
        _fail(report)
    return report


def _fit_samples(report: ClassFit, model: Model, samples: ClassSamples, fixed: Mapping[str, float] | None,
                 grid_points: int, prior: tuple[ShapePrior, np.ndarray] | None, guard: GuardRails) -> None:
    """Fit the class (:func:`fit_class_samples`) into its ``report``, with the shape ``prior`` where it
    applies, the guard rails' reasons against the fit, and another model suggested where the fit
    fails or is poor (unless its model was chosen by held-out error)."""
    levels = None if samples.group is None else _free_levels(samples, guard, report.notes)
    result = fit_class_samples(model, samples.theta_i, samples.theta_r, samples.phi, samples.brdf, fixed=fixed,
                               grid_points=grid_points, clusters=samples.block, levels=levels,
                               scenes=samples.scene if samples.scene_errors else None)
    result = _held_if_poor(result)
    _record(report, result)
    if not result["levels_converged"]:  # kept, but said: its shape may be off by about the last change
        _warn(report, f"free levels did not converge to {LEVEL_TOLERANCE:g} within {MAX_LEVEL_ITERATIONS} "
                      "repetitions of the fit (brdfcorr.fit.solver): the shape may be slightly off")
    report.notes += [held.note(name) for name, held in result["held"].items()]
    if prior is not None and model.name == PRIOR_MODEL and tuple(report.free) == KERNEL_WEIGHTS:
        _apply_prior(report, *prior, samples, levels)
        guard = dataclasses.replace(guard, max_condition=math.inf)  # the prior fixes what the geometry cannot
    fit_reasons = _fit_reasons(report, model, result["at_edge"], guard)
    report.reasons += fit_reasons
    # Another model cannot mend a sample that is too small or seen over too narrow a range
    # (_sample_reasons): it is tried only where the model itself fails or fits poorly.
    if report.model_choice is None and (fit_reasons or not report.median_angular_r2 >= POOR_R2):
        _suggest_model(report, model, samples)


def _free_levels(samples: ClassSamples, guard: GuardRails, notes: list[str]) -> Levels:
    """Each group's level free, and each scene's (a date's atmosphere, a line's calibration) too,
    unless the scenes' levels would take the signal: where the geometry spread within groups left
    once each scene's mean geometry is taken out is below the guard rail's (two lines that see
    their overlap from opposite sides: the difference between a pixel's views is then the same
    for every pixel, and a level per line absorbs it), with a note."""
    scene = samples.scene
    if scene is not None and np.unique(scene).size > 1:
        left = _within_spread(samples, scenes=True)
        if left < guard.min_vza_spread:
            notes.append(f"no level of its own per scene: the geometry spread within each {samples.levels} "
                         f"left beside the scenes' own levels, {guard.spread_short(left)}, "
                         "would leave the shape unidentified")
            scene = None
    return Levels.from_labels(samples.group, scene)


def _held_if_poor(result: dict) -> dict:
    """The fit of :func:`fit_class_samples`, or its fit with the unconstrained edge parameters held
    (``result["if_held"]``) where the fit at the edge explains too little of the angular signal
    (median angular R^2 < :data:`POOR_R2`) for its edge to be kept with a note (:func:`_fit_reasons`
    would fail the class)."""
    if result["if_held"] is None or _finite_median(result["angular_r2"]) >= POOR_R2:
        return result
    return result["if_held"]


def _pooled_if_alike(samples: ClassSamples, guard: GuardRails, pool_if_alike: bool,
                     notes: list[str]) -> tuple[ClassSamples, float | None]:
    """The samples, pooled (one level for the class, with a note) when ``pool_if_alike`` and the
    views of each group differ by less than the guard rail's view-zenith spread; and the spread
    within groups [deg] (:func:`_within_spread`), or None for pooled samples."""
    within = None if samples.group is None else _within_spread(samples)
    if pool_if_alike and within is not None and within < guard.min_vza_spread:
        notes.append(f"the views of each pixel differ by {guard.spread_short(within)}: "
                     "fitted pooled (one level for the class)")
        return dataclasses.replace(samples, group=None, levels="pooled"), None
    return samples, within


def _class_model(model: str | Model, samples: ClassSamples, fixed: Mapping[str, float] | None, grid_points: int,
                 notes: list[str]) -> tuple[Model, Mapping[str, float] | None, ModelChoice | None]:
    """The registry model of a class, ``"auto"`` chosen by held-out error
    (:func:`brdfcorr.fit.selection.choose_class_model`; the first candidate, with a note, where no
    choice is possible); the fixed shape parameters the model has; and the choice, if any."""
    choice = None
    if model == AUTO_MODEL:
        try:
            choice = choose_class_model(samples, fixed=fixed, grid_points=min(grid_points, SELECT_GRID))
            model = choice.chosen
        except FitError as error:
            model = IMAGERY_CANDIDATES[0]
            notes.append(f"no held-out choice of the model ({error}); fitted {model}")
    model = get_model(model)
    if fixed is not None and (choice is not None or notes):  # auto: only those the chosen model has
        fixed = fixed_for(model.name, fixed)
    return model, fixed, choice


def _record(report: ClassFit, result: dict) -> None:
    """Copy the solution of :func:`fit_class_samples` into the class's report."""
    report.params, report.errors = result["params"], result["errors"]
    report.free, report.covariance, report.chi2_dof = result["free"], result["covariance"], result["chi2_dof"]
    report.r2, report.rmse, report.angular_r2 = result["r2"], result["rmse"], result["angular_r2"]
    report.condition, report.fixed = result["condition"], result["fixed"]
    report.n_groups = result["n_groups"]
    report.errors_reliable, report.errors_reason = result["errors_reliable"], result["errors_reason"]


def _fail(report: ClassFit) -> None:
    """Mark a class that failed its guard rails as falling back or uncorrected, and warn
    (:class:`ClassFitWarning`, at the caller of :func:`fit_one_class`)."""
    class_id, name, fallback = report.class_id, report.name, report.fallback
    report.status = "fallback" if fallback else "uncorrected"
    action = "left uncorrected"
    if fallback:  # a coefficient set's entry is given per wavelength, a material's is not
        kind = "coefficient set" if "wavelengths" in fallback_entry(fallback, class_id, name) else "material"
        action = f"using built-in {kind} {fallback!r}"
    hint = f" ({report.better_model} explains more: median R^2 {report.better_r2:.2f})" if report.better_model else ""
    warnings.warn(f"class {class_id} ({name}): {'; '.join(report.reasons)}; {action}{hint}", ClassFitWarning,
                  stacklevel=3)


@dataclass
class ClassFitResult:
    """Result of :func:`fit_classes`: the parameter table and one report per class.

    Attributes
    ----------
    table : ParameterTable
        Fitted classes (and fallback materials); classes left uncorrected are absent.
    fits : list of ClassFit
        Per class: samples, angular spread, conditioning, R^2, RMS, errors, status and reasons.
    samples : dict of int to ClassSamples
        A subsample (at most :attr:`Sampling.keep_samples` per class) for plots.
    bad_bands : list of [float, float]
        The ranges [nm] of the bands left out of the fit (those that hold an image band), written
        to every class of the table as its ``bad_bands``; empty when none was left out.
    bands_left_out : list of float
        The centres [nm] of the image bands left out, in the images' order.
    """

    table: ParameterTable
    fits: list[ClassFit]
    samples: dict[int, ClassSamples]
    bad_bands: list[list[float]] = field(default_factory=list)
    bands_left_out: list[float] = field(default_factory=list)

    def report(self) -> list[dict[str, object]]:
        """JSON-friendly fit report, one entry per class."""
        return [fit.summary() for fit in self.fits]

    def with_source(self, source: str) -> ClassFitResult:
        """The result with ``source`` (what was fitted: command, input files) as the ``source`` of
        each fitted class's ``fit:`` block in the table (default: ``"brdfcorr.fit.fit_classes"``)."""
        fits = {fit.class_id: fit for fit in self.fits}
        classes = [entry if entry.fit is None else entry.model_copy(update={
            "fit": entry.fit.model_copy(update={"source": record_source(fits[entry.id], source)})})
            for entry in self.table.classes]
        return dataclasses.replace(self, table=self.table.model_copy(update={"classes": classes}))


def _merged(ranges) -> list[list[float]]:
    """Wavelength ranges [nm] sorted, overlapping ones merged."""
    merged: list[list[float]] = []
    for low, high in sorted((float(low), float(high)) for low, high in ranges):
        if merged and low <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], high)
        else:
            merged.append([low, high])
    return merged


def _without_bad_bands(scenes: list, wavelengths, bad_bands) -> tuple[list, list | None, list, list]:
    """The scenes without the bands whose centres [nm] lie in ``bad_bands``, the remaining
    wavelengths, the ranges that held a band (merged) and the centres left out. Nothing is left
    out without wavelengths; an InputError when every band would be."""
    if wavelengths is None or not len(bad_bands):
        return scenes, wavelengths, [], []
    centres = np.asarray(wavelengths, dtype=float)
    bad = in_ranges(centres, bad_bands)
    if not bad.any():
        return scenes, wavelengths, [], []
    if bad.all():
        raise InputError(f"every band ({centres.min():g}-{centres.max():g} nm) lies in the bad-band ranges "
                         f"{', '.join(f'{low:g}-{high:g}' for low, high in bad_bands)} nm: nothing to fit")
    used = [[low, high] for low, high in bad_bands if in_ranges(centres, [(low, high)]).any()]
    kept = [scene.isel({scene.dims[0]: np.flatnonzero(~bad)}) for scene in scenes]
    return kept, centres[~bad].tolist(), _merged(used), centres[bad].tolist()


def _with_default_model(models: ClassModels | str | Model) -> ClassModels:
    """``models`` as :class:`ClassModels` (a model or its name stands for ``ClassModels(model)``),
    with :data:`DEFAULT_MODEL` where it names none."""
    if not isinstance(models, ClassModels):
        models = ClassModels(models)
    return dataclasses.replace(models, model=DEFAULT_MODEL) if models.model is None else models


def _models_in_play(models: ClassModels) -> list[str]:
    """The registry names of every model ``models`` may fit: the default, the classes' own, and
    the candidates of a held-out choice (``auto``)."""
    names = [getattr(model, "name", model) for model in (models.model, *(models.class_models or {}).values())]
    return [candidate for name in names for candidate in (IMAGERY_CANDIDATES if name == AUTO_MODEL else (name,))]


def _prior(models: ClassModels, wavelengths: Sequence[float] | None) -> tuple[ShapePrior, np.ndarray] | None:
    """The shape prior of ``models`` with its ratios at the band centres ``wavelengths`` [nm]
    (:func:`brdfcorr.fit.prior.prior_ratios`), or None without a prior."""
    if models.prior is None:
        return None
    if wavelengths is None:
        raise InputError(f"the prior {models.prior.coefficients} needs the bands' wavelengths (band "
                         "descriptions or a wavelength tag; a chain's inputs.wavelengths)")
    return models.prior, prior_ratios(models.prior.coefficients, wavelengths)


def _by_name(model: str | Model) -> str | Model:
    """A registered model by its name (a process pool's task takes it so: some models' kernels are
    closures, which do not pickle); another as it is."""
    return model.name if isinstance(model, Model) and REGISTRY.get(model.name) is model else model


def _fit_recording(args: tuple, options: dict) -> tuple[ClassFit, list[tuple[str, type[Warning]]]]:
    """:func:`fit_one_class` with its warnings recorded, as (message, category): a process pool's
    task of :func:`fit_classes`, whose warnings would be lost in the worker process."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = fit_one_class(*args, **options)
    return fit, [(str(warning.message), warning.category) for warning in caught]


def _thinned(samples: ClassSamples, keep: int) -> ClassSamples:
    """About ``keep`` of a class's samples, evenly spaced, for plots (angles and BRDF only)."""
    step = max(1, samples.theta_i.size // keep)
    return ClassSamples(samples.theta_i[::step], samples.theta_r[::step], samples.phi[::step], samples.brdf[::step])


def fit_classes(images, classes, angles, models: ClassModels | str | Model = ClassModels(), *,
                sampling: Sampling = Sampling(), wavelengths: Sequence[float] | None = None,
                guard: GuardRails = GuardRails(), progress=None, clusters=None,
                executor: concurrent.futures.Executor | None = None) -> ClassFitResult:
    """Fit a BRDF model per class (shape per class, intensities per band) from imagery.

    Parameters
    ----------
    images, classes, angles :
        One or many scenes, or a cube with a ``time`` dimension (one scene per date, fitted
        together: with the default ``sampling`` each pixel's level is free); see
        :func:`sample_classes`.
    models : ClassModels or str or Model, default ClassModels()
        The classes to fit, their names, surface models (by default "torrance_sparrow" for every
        class), fixed shape parameters (by default k = 0.25 for the Torrance-Sparrow models) and
        fallback materials. A model name or model alone stands for ``ClassModels(model)``. A class
        that fails its guard rails gets its fallback material or, without one, is left out of the
        table (left uncorrected, and flagged by the correction); either way a
        :class:`ClassFitWarning` says so, as it names the classes that per-class settings name
        but the class maps do not hold (:meth:`ClassModels.unused`).
    sampling : Sampling, default Sampling()
        Samples per class, seed, reflectance scale, bad bands and spatial block size of the sampler
        (:func:`sample_classes`; the errors are cluster-robust over the blocks, and over the
        scenes too with ``errors_cluster="two-way"``), and the samples per class kept in the
        result for plots.
    wavelengths : sequence of float, optional
        Band centres [nm]; default: the images' ``wavelength`` coordinate if present. Written to
        the table so that it can be applied to other sensors by interpolation.
    guard : GuardRails
        Minimum samples, view-zenith spread, conditioning and R^2 a class must meet, with its
        shape parameters inside their search ranges. A class that fails, or fits poorly, gets a
        suggested better model in its report if another one explains clearly more.
    progress : callable, optional
        Called as ``progress(class_id)`` after each class (e.g. a progress bar's update).
    clusters : DataArray or array (y, x), or a list of them, optional
        A cluster layer per scene (integer ids of the units whose pixels share their errors: a
        composite's day-of-year band, a flight-line id): the errors are cluster-robust over these
        instead of square blocks of ``sampling.block_size``, and the held-out folds of ``auto``
        hold out whole clusters (:func:`sample_classes`).
    executor : concurrent.futures.Executor, optional
        Fits the classes (each class's fit is independent of the others'), e.g. a
        :class:`~concurrent.futures.ProcessPoolExecutor` over the cores (``brdfcorr fit-classes
        --workers N``): the same fits as without one, one class after the other in this process;
        the classes' warnings are given here, in the classes' order.

    Returns
    -------
    ClassFitResult

    Notes
    -----
    The bands whose centres lie in ``sampling.bad_bands`` [nm] (default :data:`WATER_VAPOUR_BANDS`;
    ``()``: none) are left out of the fit. Every class of the table lists those that held a band as
    its ``bad_bands``: it has no parameters there, and the correction passes those bands through
    uncorrected (QA flag ``band_uncorrected``). A fit with bad bands gives the other bands the
    numbers of a fit of the image without them. Needs band wavelengths (without them nothing is
    left out).
    """
    models = _with_default_model(models)
    check_fixed(models.fixed, _models_in_play(models))
    if sampling.errors_cluster not in ERROR_CLUSTERS:
        raise ParameterError(f"errors cluster {sampling.errors_cluster!r}: use one of {', '.join(ERROR_CLUSTERS)}")
    scenes, classes, angles, clusters = scene_lists(images, classes, angles, clusters)
    scenes = [with_wavelengths(scene) if isinstance(scene, xr.DataArray) else scene for scene in scenes]
    if wavelengths is None and "wavelength" in scenes[0].coords:
        wavelengths = np.asarray(scenes[0]["wavelength"].values, dtype=float).tolist()
    scenes, wavelengths, used_ranges, left_out = _without_bad_bands(scenes, wavelengths, sampling.bad_bands)
    pooled = sample_classes(scenes, classes, angles, class_ids=models.class_ids, sampling=sampling, clusters=clusters,
                            min_repeated=guard.min_samples, dates=isinstance(images, xr.DataArray))
    unused = models.unused(pooled)
    if unused is not None:
        warnings.warn(unused, ClassFitWarning, stacklevel=2)
    prior = _prior(models, wavelengths)
    tasks = {}
    for class_id, samples in pooled.items():
        samples.scene_errors = sampling.errors_cluster == "two-way"
        tasks[class_id] = ((class_id, models.name_of(class_id), _by_name(models.model_of(class_id)), samples),
                           {"fixed": models.fixed, "guard": guard, "fallback": models.fallback_of(class_id),
                            "prior": prior, "pool_if_alike": sampling.levels == "auto"})
    futures = {} if executor is None else {key: executor.submit(_fit_recording, *task) for key, task in tasks.items()}
    fits, entries, kept = [], [], {}
    for class_id, samples in pooled.items():
        if executor is None:
            args, options = tasks[class_id]
            fit = fit_one_class(*args, **options)
        else:  # the class's warnings, given here as they would have been in this process
            fit, caught = futures[class_id].result()
            for message, category in caught:
                warnings.warn(message, category, stacklevel=2)
        if samples.note is not None:
            fit.notes.append(samples.note)
        fits.append(fit)
        entry = class_entry(fit, wavelengths, "brdfcorr.fit.fit_classes", used_ranges or None)
        entries += [] if entry is None else [entry]
        kept[class_id] = _thinned(samples, sampling.keep_samples)
        if progress is not None:
            progress(class_id)
    return ClassFitResult(table=ParameterTable(classes=entries), fits=fits, samples=kept, bad_bands=used_ranges,
                          bands_left_out=left_out)

