"""Choosing a surface model by its held-out error (``--model auto``).

A model with more parameters always fits the data it was fitted on at least as well; whether it
describes the surface better shows only on data it has not seen. :func:`choose_model` (goniometer
measurements) and :func:`choose_class_model` (a class's pixels from imagery) fit every candidate
model on k - 1 folds of the data and score it on the fold left out, for each of k folds:

- goniometer measurements: folds of geometries, drawn at random with a fixed seed;
- imagery: folds of spatial blocks (:attr:`brdfcorr.fit.sampling.ClassSamples.block`; on scenes
  that share one grid a block is the same ground in every scene, so all its dates are held out
  together; elsewhere unique to its scene): a block's pixels, which share their texture and cover,
  are never on both sides. Where the fit leaves each pixel's or patch's level free
  (:mod:`brdfcorr.fit.within`), the differences within groups are what is predicted.

The score of a fold is the held-out mean squared error (weighted by 1/sigma^2 where the
measurements have errors; by the bands' inverse variances for imagery, as the fit weights them).
The rule is the one-standard-error rule of Hastie, Tibshirani & Friedman [1]_ (section 7.10) on
paired folds: the candidate with the lowest mean error is the best; the chosen model is the one with
the fewest free parameters whose mean excess error over the best, fold by fold, is within one
standard error of that excess (its standard deviation over the folds / sqrt(k)). So a more complex
model wins only where it beats the simpler ones by more than the standard error of that paired
difference (a small but consistent one decides), and never by round-off (:data:`ROUND_OFF`).

References
----------
.. [1] T. Hastie, R. Tibshirani, J. Friedman (2009): The Elements of Statistical Learning, 2nd ed.,
   Springer, section 7.10 (cross-validation, the one-standard-error rule).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from brdfcorr.defaults import AUTO_MODEL
from brdfcorr.errors import BrdfcorrError, FitError, ParameterError
from brdfcorr.fit.goniometer import fit_brdf, fit_from
from brdfcorr.fit.measurements import Measurements
from brdfcorr.fit.profile import _profile
from brdfcorr.fit.shape_search import _newton_polish, _search, _search_subset
from brdfcorr.fit.shapes import DEFAULT_FIXED, _free_shape
from brdfcorr.fit.within import Levels
from brdfcorr.models import get_model

__all__ = [
    "AUTO",
    "GONIOMETER_CANDIDATES",
    "IMAGERY_CANDIDATES",
    "CandidateScore",
    "ModelChoice",
    "choose_model",
    "choose_class_model",
    "fixed_for",
    "settings_for",
    "check_fixed",
]

#: The model name that asks for the choice by held-out error (CLI ``--model auto``, tables, chains).
AUTO = AUTO_MODEL
#: Candidates for goniometer measurements: one lobe (specular: Torrance-Sparrow; backscatter: the
#: MODIS kernels, RPV) and two lobes (:mod:`brdfcorr.models.two_lobe`).
GONIOMETER_CANDIDATES: tuple[str, ...] = (
    "torrance_sparrow", "ross_thick_li_sparse", "rpv", "ross_li_ts", "ross_li_peak", "rpv_peak",
)
#: Candidates for imagery: those whose shape search stays cheap on many pixels and bands (at most
#: three free shape parameters).
IMAGERY_CANDIDATES: tuple[str, ...] = ("ross_thick_li_sparse", "torrance_sparrow", "rpv", "ross_li_ts")
#: Folds of the cross-validation, and the seed of their random assignment.
FOLDS = 5
SEED = 0
#: The imagery choice is made on a seeded subsample of the class: this many pixels and at most
#: ``SELECT_BANDS`` evenly spaced bands (the full fit of the chosen model then uses every sample).
SELECT_SAMPLES = 10_000
SELECT_BANDS = 8
#: ... and each fold's shape search starts from a grid of this many points per free shape
#: parameter (the Nelder-Mead refinement follows): RPV's three free shape parameters make 125
#: grid points instead of 729, and ``fit-classes --model auto`` costs a few single fits.
SELECT_GRID = 5


@dataclass(frozen=True)
class CandidateScore:
    """One candidate model's cross-validation.

    Attributes
    ----------
    model : str
        Registry name.
    n_free : int
        Free parameters of the fit (intensities times bands plus free shape parameters).
    fold_errors : tuple of float
        Held-out mean squared error of each fold (weighted; [sr^-2] for unweighted measurements);
        empty when the candidate could not be fitted.
    heldout_r2 : float
        ``1 - PRESS / SS_total`` [-] over every held-out value (median over bands for imagery).
    problem : str
        Why the candidate could not be fitted (empty when it was).
    """

    model: str
    n_free: int
    fold_errors: tuple[float, ...]
    heldout_r2: float
    problem: str = ""

    @property
    def mean_error(self) -> float:
        return float(np.mean(self.fold_errors)) if self.fold_errors else math.inf


@dataclass(frozen=True)
class ModelChoice:
    """The outcome of a choice by held-out error.

    Attributes
    ----------
    chosen : str
        The model chosen by the one-standard-error rule.
    best : str
        The candidate with the lowest mean held-out error.
    scores : tuple of CandidateScore
        Every candidate, in the order tried.
    folds : int
        Number of folds.
    grouping : str
        What the folds are made of (``"geometries"``, ``"spatial blocks"``, ``"samples"``).
    """

    chosen: str
    best: str
    scores: tuple[CandidateScore, ...]
    folds: int
    grouping: str

    def score_of(self, model: str) -> CandidateScore:
        return next(score for score in self.scores if score.model == model)

    def rows(self) -> list[dict[str, object]]:
        """One JSON-friendly row per candidate: model, free parameters, held-out R^2, mean error and
        its spread over the folds, whether chosen, and why it could not be fitted."""
        return [
            {
                "model": score.model,
                "n_free": score.n_free,
                "heldout_r2": None if not math.isfinite(score.heldout_r2) else round(score.heldout_r2, 4),
                "mean_error": None if not score.fold_errors else score.mean_error,
                "fold_sd": None if len(score.fold_errors) < 2 else float(np.std(score.fold_errors, ddof=1)),
                "chosen": score.model == self.chosen,
                "problem": score.problem,
            }
            for score in self.scores
        ]

    def summary(self) -> dict[str, object]:
        """JSON-friendly: the chosen and best model, the folds and every candidate's row."""
        return {"chosen": self.chosen, "best": self.best, "folds": self.folds, "grouping": self.grouping,
                "rule": "one standard error (paired folds)", "candidates": self.rows()}

    def table(self) -> str:
        """The candidates as a plain-text table for the console."""
        lines = [f"model choice by {self.folds}-fold cross-validation over {self.grouping}:",
                 f"  {'model':<22} {'free':>5} {'held-out R2':>12}  {'error (mean +- sd)':<24}"]
        for row in self.rows():
            r2 = "-" if row["heldout_r2"] is None else f"{row['heldout_r2']:.3f}"
            if row["mean_error"] is None:
                error = f"not fitted: {row['problem']}"
            else:
                error = f"{row['mean_error']:.3g} +- {row['fold_sd'] or 0:.2g}"
            mark = "  <- chosen" if row["chosen"] else ""
            lines.append(f"  {row['model']:<22} {row['n_free']:>5} {r2:>12}  {error}{mark}")
        return "\n".join(lines)


#: Held-out errors [relative to the data's mean weighted square] below which candidates tie
#: (:func:`_one_se_choice`): the optimizer's round-off, not a difference between models.
ROUND_OFF = 1e-10


def _one_se_choice(scores: Sequence[CandidateScore], scale: float = 0.0) -> tuple[str, str]:
    """(chosen, best) by the paired one-standard-error rule (module docstring). Excesses within
    :data:`ROUND_OFF` of ``scale`` (the data's mean weighted square) are ties: on noise-free or
    constant data every candidate predicts to round-off (1e-14 to 1e-22), and those errors chose
    the most complex model."""
    fitted = [score for score in scores if score.fold_errors]
    if not fitted:
        problems = "; ".join(f"{score.model}: {score.problem}" for score in scores)
        raise FitError(f"no candidate model could be fitted ({problems})")
    best = min(fitted, key=lambda score: score.mean_error)
    for score in sorted(fitted, key=lambda score: score.n_free):  # stable: ties keep the given order
        excess = np.subtract(score.fold_errors, best.fold_errors)
        spread = np.std(excess, ddof=1) / math.sqrt(excess.size) if excess.size > 1 else 0.0
        if excess.mean() <= max(spread, ROUND_OFF * scale):
            return score.model, best.model
    return best.model, best.model  # unreachable: the best's own excess is 0


def _folds(groups: np.ndarray, folds: int, seed: int) -> np.ndarray:
    """A fold number per sample: the distinct groups shuffled (seeded) and dealt round-robin."""
    distinct, inverse = np.unique(groups, return_inverse=True)
    order = np.random.default_rng(seed).permutation(distinct.size)
    fold_of_group = np.empty(distinct.size, dtype=np.int64)
    fold_of_group[order] = np.arange(distinct.size) % folds
    return fold_of_group[inverse.reshape(-1)]


def check_fixed(fixed: Mapping[str, object] | None, models: Sequence[str], what: str = "fixed parameter") -> None:
    """Raise :class:`~brdfcorr.errors.ParameterError` where a name of ``fixed`` is a different
    parameter in two of ``models`` (registry names), as ``k`` is RPV's Minnaert-like exponent and
    the Torrance-Sparrow models' absorption index: one value, applied to every model that has the
    name (:func:`fixed_for`), would hold both. ``what`` names the setting in the message (a
    starting value, a bound)."""
    for key in dict(fixed or {}):
        meanings: dict[int, tuple[str, list[str]]] = {}
        for name in dict.fromkeys(models):
            model = get_model(name)
            if key in model.parameter_names:
                parameter = model.parameter(key)
                meanings.setdefault(id(parameter), (parameter.description, []))[1].append(name)
        if len(meanings) > 1:
            which = "; ".join(f"{description} in {', '.join(names)}" for description, names in meanings.values())
            raise ParameterError(f"the {what} {key} is not the same parameter in the models fitted here "
                                 f"({which}): name one model, or leave it out")


T = TypeVar("T")


def settings_for(name: str, settings: Mapping[str, T] | None) -> dict[str, T]:
    """Those of ``settings`` (fixed values, starting values or bounds by parameter name) that model
    ``name`` has: what a fit over several candidate models gives each one."""
    names = get_model(name).parameter_names
    return {key: value for key, value in dict(settings or {}).items() if key in names}


def fixed_for(name: str, fixed: Mapping[str, float] | None) -> dict[str, float]:
    """The parameters model ``name`` holds fixed: its defaults (:data:`DEFAULT_FIXED`) with those
    of ``fixed`` that it has (:func:`settings_for`)."""
    return {**DEFAULT_FIXED.get(name, {}), **settings_for(name, fixed)}


def _cross_validate(name: str, fold: np.ndarray, n_free: int, predict: Callable[[int], np.ndarray],
                    data: np.ndarray, weights: np.ndarray) -> CandidateScore:
    """Held-out errors of one candidate: ``predict(number)`` returns the predictions at the rows of
    fold ``number`` (n_test, B) from a fit on the other folds' rows."""
    predictions = np.full(data.shape, np.nan)
    errors = []
    try:
        for number in range(int(fold.max()) + 1):
            test = fold == number
            predictions[test] = predict(number)
            errors.append(float(np.mean((predictions[test] - data[test]) ** 2 * weights[test])))
    except (BrdfcorrError, ValueError, np.linalg.LinAlgError) as error:
        return CandidateScore(name, n_free, (), math.nan, str(error))
    if not np.all(np.isfinite(errors)):
        return CandidateScore(name, n_free, (), math.nan, "non-finite predictions")
    press = np.sum((predictions - data) ** 2, axis=0)
    total = np.sum((data - data.mean(axis=0)) ** 2, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(total > 0, 1.0 - press / total, np.nan)
    return CandidateScore(name, n_free, tuple(errors), float(np.nanmedian(r2)) if np.any(np.isfinite(r2)) else math.nan)


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """A fold's fit without its warnings: they say nothing about the choice."""
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        yield


def _full_fit(name: str, settings: Mapping[str, Mapping], angles: list[np.ndarray], data: np.ndarray,
              errors: np.ndarray | None) -> dict[str, float] | None:
    """The free parameters of model ``name`` fitted to all the measurements (:func:`fit_brdf`,
    every start), where it can be fitted: the start of its folds' fits (:func:`_fold_fit`)."""
    with _quiet():
        try:
            result = fit_brdf(name, *angles, data[:, 0], errors, **settings)
        except (BrdfcorrError, ValueError, np.linalg.LinAlgError):
            return None  # the folds start from every point, and say why
    return {parameter: float(result.params[parameter]) for parameter in result.free}


def _fold_fit(name: str, settings: Mapping[str, Mapping], angles: list[np.ndarray], data: np.ndarray,
              errors: np.ndarray | None, train: np.ndarray, test: np.ndarray,
              start: Mapping[str, float] | None = None) -> np.ndarray:
    """The predictions (n_test, 1) [sr^-1] at the ``test`` rows of model ``name`` fitted to the
    ``train`` rows (boolean masks) of goniometer measurements with ``settings`` (``fixed``,
    ``initial`` and ``bounds`` of :func:`~brdfcorr.fit.goniometer.fit_brdf`): from ``start`` (the
    fit to all the measurements: one local optimization, :func:`fit_from`) where it converges,
    else from every start. One task of :func:`choose_model`, a module function so that a process
    pool can run it."""
    measurements = (*(a[train] for a in angles), data[train, 0], None if errors is None else errors[train])
    with _quiet():
        result = None
        if start is not None:
            with contextlib.suppress(FitError):
                result = fit_from(name, *measurements, start=start, fixed=settings["fixed"],
                                  bounds=settings["bounds"])
        if result is None:
            result = fit_brdf(name, *measurements, **settings)
        return np.asarray(result.predict(*(a[test] for a in angles)), dtype=float)[:, None]


def _fold_prediction(task: tuple, fold: np.ndarray, start: Mapping[str, float] | None, number: int) -> np.ndarray:
    """:func:`_fold_fit` of fold ``number`` of a candidate (``task``: its arguments before the masks)."""
    return _fold_fit(*task, fold != number, fold == number, start)


def _submitted_prediction(futures: list[concurrent.futures.Future], number: int) -> np.ndarray:
    return futures[number].result()


def choose_model(
    measurements: Measurements, *,
    candidates: Sequence[str] = GONIOMETER_CANDIDATES,
    fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    folds: int = FOLDS,
    progress: Callable[[str], object] | None = None,
    executor: concurrent.futures.Executor | None = None,
) -> ModelChoice:
    """Choose the model of goniometer measurements by k-fold cross-validation over geometries.

    Parameters
    ----------
    measurements : Measurements
        The measurements (:class:`~brdfcorr.fit.measurements.Measurements`: illumination zenith,
        view zenith and relative azimuth [deg], BRDF [sr^-1]); where they have 1-sigma errors
        (``sigma``), the held-out errors are weighted by 1/sigma^2.
    candidates : sequence of str, default :data:`GONIOMETER_CANDIDATES`
        Registered models to try.
    fixed : mapping, optional
        Parameters held fixed in every candidate that has them (besides each model's defaults,
        k = 0.25 for the Torrance-Sparrow lobes).
    initial, bounds : mapping, optional
        Starting values and bounds (as for :func:`~brdfcorr.fit.goniometer.fit_brdf`) of every
        candidate that has the parameter: each candidate is scored as it would be fitted.
    folds : int, default 5
        Folds (at most the number of measurements), geometries assigned to them at random with
        the seed :data:`SEED`. Each candidate is first fitted to all the measurements (every
        start of :func:`~brdfcorr.fit.goniometer.fit_brdf`); each fold's fit starts from that
        fit alone (one local optimization, :func:`~brdfcorr.fit.goniometer.fit_from`; every start
        where it does not converge): the choice costs the candidates' fits and one local
        optimization a fold, where every fold's fit started 15 times (``brdfcorr fit --model
        auto`` on the demo's roof tile: 3.7 s instead of 8.1 s on 2 cores, the same table).
    progress : callable, optional
        Called as ``progress(name)`` after each candidate's folds are fitted (a progress bar's
        update; a candidate takes seconds).
    executor : concurrent.futures.Executor, optional
        Runs the candidates' fold fits (candidates x folds independent fits, all submitted at
        once), e.g. a :class:`~concurrent.futures.ProcessPoolExecutor` over the cores
        (``brdfcorr fit --model auto --workers N``). The choice is the same as without one, the
        fits in this process one after the other.

    Returns
    -------
    ModelChoice
        Fit the chosen model on all the measurements with :func:`brdfcorr.fit.goniometer.fit_brdf`.

    Raises
    ------
    brdfcorr.errors.FitError
        When no candidate can be fitted, or there are fewer than 2 measurements per fold.
    brdfcorr.errors.ParameterError
        When a name of ``fixed``, ``initial`` or ``bounds`` is a different parameter in two
        candidates (:func:`check_fixed`), before any fit.
    """
    for what, given in (("fixed parameter", fixed), ("starting value of parameter", initial),
                        ("bound of parameter", bounds)):
        check_fixed(given, candidates, what)
    angles = [measurements.theta_i, measurements.theta_r, measurements.phi]
    data, errors = measurements.brdf.reshape(-1, 1), measurements.sigma
    if data.shape[0] < 2 * folds:
        raise FitError(f"{data.shape[0]} measurements are too few for a {folds}-fold choice of the model "
                       f"(at least {2 * folds}); name a model")
    weights = np.ones_like(data) if errors is None else (1.0 / errors**2)[:, None]
    fold = _folds(np.arange(data.shape[0]), folds, SEED)
    settings = {name: {"fixed": fixed_for(name, fixed), "initial": settings_for(name, initial) or None,
                       "bounds": settings_for(name, bounds) or None} for name in candidates}
    full = {name: (name, settings[name], angles, data, errors) for name in candidates}
    if executor is not None:  # the fits to all the measurements at once, then each candidate's folds
        starts = {name: executor.submit(_full_fit, *task) for name, task in full.items()}
        submitted = {name: [executor.submit(_fold_fit, *full[name], fold != number, fold == number,
                                            starts[name].result()) for number in range(folds)]
                     for name in candidates}
    scores = []
    for name in candidates:
        if executor is None:  # one fit after the other, as the score asks for them
            start = _full_fit(*full[name])
            predict = functools.partial(_fold_prediction, full[name], fold, start)
        else:
            predict = functools.partial(_submitted_prediction, submitted[name])
        n_free = len(get_model(name).parameters) - len(fixed_for(name, fixed))
        scores.append(_cross_validate(name, fold, n_free, predict, data, weights))
        if progress is not None:
            progress(name)
    chosen, best = _one_se_choice(scores, float(np.mean(data**2 * weights)))
    return ModelChoice(chosen, best, tuple(scores), folds, "geometries")


def _subsample(samples, max_samples: int, max_bands: int):
    """A seeded subsample of a class's samples and evenly spaced bands: angles, brdf, blocks, and
    the free levels (:mod:`brdfcorr.fit.within`) of the samples' groups, whole groups drawn, if
    they have groups."""
    n = np.size(samples.theta_i)
    levels = None if samples.group is None else Levels.from_labels(samples.group)
    if levels is None:
        rows = np.sort(np.random.default_rng(SEED).choice(n, min(n, max_samples), replace=False))
    else:
        subset = _search_subset(n, max_samples, levels)
        rows = np.arange(n) if subset is None else subset
        levels = levels.subset(rows)
    data = np.asarray(samples.brdf, dtype=float).reshape(n, -1)
    bands = np.unique(np.linspace(0, data.shape[1] - 1, min(data.shape[1], max_bands)).round().astype(int))
    angles = [np.asarray(a, dtype=float).reshape(-1)[rows] for a in (samples.theta_i, samples.theta_r, samples.phi)]
    blocks = None if samples.block is None else np.asarray(samples.block).reshape(-1)[rows]
    return angles, data[np.ix_(rows, bands)], blocks, levels


def _choice_data(samples) -> tuple[list[np.ndarray], np.ndarray, np.ndarray | None, Levels | None, np.ndarray]:
    """The seeded subsample of the choice (:func:`_subsample`): angles [deg], BRDF (n, b) [sr^-1],
    blocks and levels, with free levels only the groups that can be fitted within, and the data
    predicted: the BRDF, or with free levels each group's views relative to it, within groups."""
    angles, raw, blocks, levels = _subsample(samples, SELECT_SAMPLES, SELECT_BANDS)
    if levels is None:
        return angles, raw, blocks, None, raw
    usable = levels.usable(raw)
    angles, raw, levels = [a[usable] for a in angles], raw[usable], levels.subset(usable)
    blocks = None if blocks is None else blocks[usable]
    return angles, raw, blocks, levels, levels.demean(levels.relative(raw)[0])


def _fold_count(groups: np.ndarray, folds: int) -> int:
    """``folds``, or fewer where there are fewer ``groups``; at least 2 (else :class:`FitError`)."""
    folds = min(folds, np.unique(groups).size)
    if folds < 2:
        raise FitError("the class's samples lie in one spatial block: no held-out choice of the model is "
                       "possible; name a model (or use a smaller block size)")
    return folds


def choose_class_model(
    samples, *,
    candidates: Sequence[str] = IMAGERY_CANDIDATES,
    fixed: Mapping[str, float] | None = None,
    folds: int = FOLDS,
    grid_points: int = SELECT_GRID,
) -> ModelChoice:
    """Choose the model of one class's pixels by k-fold cross-validation over spatial blocks.

    Parameters
    ----------
    samples : ClassSamples
        The class's samples (:class:`brdfcorr.fit.sampling.ClassSamples`); their ``block`` ids
        group the folds (without blocks, single samples are).
    candidates : sequence of str, default :data:`IMAGERY_CANDIDATES`
        Registered surface models to try.
    fixed : mapping, optional
        Shape parameters held fixed in every candidate that has them.
    folds : int, default 5
        Folds; fewer when there are fewer blocks (at least 2 are needed).
    grid_points : int, default :data:`SELECT_GRID`
        Coarse-grid points per free shape parameter of each fold's search.

    Returns
    -------
    ModelChoice

    Notes
    -----
    On a seeded subsample (:data:`SELECT_SAMPLES` pixels, :data:`SELECT_BANDS` bands), each
    candidate's shape is searched once over all the samples (the solver's grid and Nelder-Mead,
    variable projection, the per-band intensities by non-negative least squares); each fold's fit
    starts from that shape (damped Newton steps, :func:`~brdfcorr.fit.shape_search._newton_polish`;
    Nelder-Mead where the curvature is not positive definite). The folds' fits thus start from a
    fit that has seen the held-out fold, as every candidate's do; a fold's own grid search found a
    worse minimum at times, and took 1.5 to 2.5 times as long. The held-out error of a band is
    weighted by its inverse variance, as the fit weights the bands.
    """
    check_fixed(fixed, candidates)
    angles, raw, blocks, levels, data = _choice_data(samples)
    groups, grouping = (blocks, "spatial blocks") if blocks is not None else (np.arange(data.shape[0]), "samples")
    folds = _fold_count(groups, folds)
    fold = _folds(groups, folds, SEED)
    variance = data.var(axis=0)
    weights = np.broadcast_to(np.where(variance > 0, 1.0 / np.where(variance > 0, variance, 1.0), 0.0), data.shape)
    scores = []
    for name in candidates:
        model = get_model(name)
        model_fixed = fixed_for(name, fixed)
        free = _free_shape(model, model_fixed)
        n_free = len(model.linear) * data.shape[1] + len(free)

        with _quiet():  # the shape fitted to every sample: where each fold's fit starts
            whole = _profile(model, *angles, raw, model_fixed, levels=levels)
            start = _search(whole, free, grid_points) if free else {}

        def predict(number, model=model, model_fixed=model_fixed, start=start):
            train, test = fold != number, fold == number
            part = lambda rows: None if levels is None else levels.subset(rows)  # noqa: E731
            with _quiet():
                profile = _profile(model, *(a[train] for a in angles), raw[train], model_fixed, levels=part(train))
                shape = _newton_polish(profile, start) if start else {}
                intensities, _ = profile.solve(profile.design(shape))
                held_out = _profile(model, *(a[test] for a in angles), raw[test], model_fixed, levels=part(test))
                prediction = held_out.design(shape) @ intensities
                # With free levels the fit is in BRDF units at its class mean level; the target is relative.
                return prediction if levels is None else prediction / profile.scale

        scores.append(_cross_validate(name, fold, n_free, predict, data, weights))
    chosen, best = _one_se_choice(scores, float(np.mean(data**2 * weights)))
    return ModelChoice(chosen, best, tuple(scores), folds, grouping)
