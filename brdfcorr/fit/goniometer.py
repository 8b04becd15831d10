"""Fit BRDF models to goniometer measurements by weighted least squares, as paper 003 did.

:func:`fit_brdf` fits any model of the registry (:mod:`brdfcorr.models`) to BRDF measurements
with :func:`scipy.optimize.least_squares`, holding any subset of the parameters fixed (paper 003
fixes k = 0.25), within the registry's physical bounds, from several deterministic starting points.
It returns a :class:`FitResult` with 1-sigma errors from the covariance matrix, chi^2, the degrees
of freedom, the residuals and the parameter correlations, and warns with
:class:`NonIdentifiableWarning` when the measurements cannot separate the parameters (paper 003,
section 4: n, k and t1 trade off).

The helpers that turn a model and a user's ``fixed``/``initial``/``bounds`` into a bounded problem
(:mod:`brdfcorr.fit.bounds`) and that find starting values (:func:`_starting_points`) do not depend
on where the measurements come from. The covariance, correlations and identifiability messages
live in :mod:`brdfcorr.fit.identifiability`; :class:`FitResult` and the parameter-table entries
made from fits (:func:`spectral_table_entry`) in :mod:`brdfcorr.fit.results` (importable from here
as well).

References
----------
.. [1] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII, section 4, eq. 4 and Table 1.
.. [2] S. Brandt (1992): Datenanalyse. BI-Wissenschaftsverlag, p. 276 (errors of a non-linear
   least-squares fit from the linearized model, i.e. the inverse of J^T W J).
.. [3] W. H. Press et al. (2007): Numerical Recipes, 3rd ed., section 15.4-15.5 (chi^2 fitting,
   covariance from the design matrix, scaling by chi^2/dof when the errors are unknown).
"""

from __future__ import annotations

import functools
import itertools
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, lsq_linear

from brdfcorr.errors import BrdfcorrWarning, FitError
from brdfcorr.fit.bounds import OPEN_BOUND_FLOOR, _free_parameters  # noqa: F401  (importable from here as before)
from brdfcorr.fit.energy import albedo_excess
from brdfcorr.fit.identifiability import (
    CONDITION_LIMIT,  # noqa: F401  (importable from here as before the split)
    CORRELATION_LIMIT,
    correlation_matrix,
    hc3_covariance,
    identifiability_messages,
    jacobian_covariance,
    other_minima,
    robust_problem,
)
from brdfcorr.fit.measurements import Measurements, check_measurements
from brdfcorr.fit.results import FitResult, format_with_error, spectral_table_entry
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import Model, get_model

__all__ = [
    "AlbedoWarning",
    "ErrorAnalysis",
    "FitResult",
    "FitWarning",
    "NonIdentifiableWarning",
    "fit_brdf",
    "fit_from",
    "fit_measurements",
    "fit_wavelengths",
    "spectral_table_entry",
    "format_with_error",
]

#: Multiplicative grids of starting values around the start of scale parameters (range (0, inf)):
#: the first one (the width parameter w, c or sigma, which comes before n in the registry) gets the
#: finer grid.
_FIRST_GRID = (0.25, 0.5, 1.0, 2.0, 4.0)
_OTHER_GRID = (1.0 / 3.0, 1.0, 3.0)
# Residuals of parameter sets where the model overflows; finite so the optimizer can back off.
_NON_FINITE_RESIDUAL = 1e100


class FitWarning(BrdfcorrWarning):
    """A fit finished, but one of its results needs care (a parameter at a bound, ...)."""


class NonIdentifiableWarning(FitWarning):
    """The measurements do not determine some free parameters separately (large correlations or
    an ill-conditioned or singular Jacobian). Fix one of them (paper 003 fixes k = 0.25)."""


class AlbedoWarning(FitWarning):
    """The fitted BRDF reflects more than it receives (albedo > 1 at a measured illumination
    zenith): impossible for a surface, most often measurements in percent or reflectance factors
    (pi * BRDF) instead of BRDF [sr^-1] (:func:`brdfcorr.fit.energy.albedo_excess`)."""


@dataclass(frozen=True)
class ErrorAnalysis:
    """How :func:`fit_brdf` estimates the errors of the fitted parameters and when it warns that
    the measurements do not determine them.

    Attributes
    ----------
    scale_errors : bool or None, default None
        Multiply the covariance by chi^2/dof (True), or not (False). None: with ``sigma`` the
        errors are those implied by the measurement errors alone (Brandt [2]_, as in paper 003,
        Table 1) and chi^2/dof says separately how well the model fits (well above 1: the errors
        are too small by about sqrt(chi^2/dof)); without ``sigma`` they come from the residuals,
        heteroscedasticity-robust (HC3 sandwich, MacKinnon and White 1985), since goniometer
        noise is relative and the BRDF spans orders of magnitude: ``(J^T J)^-1 chi^2/dof``, which
        assumes equal noise, gave errors 2-5x too small on paper 003's materials with 4 % noise.
        Where the sandwich is undefined (a measurement of leverage ~1) the errors are scaled, with
        a :class:`FitWarning`.
    correlation_limit : float, default :data:`~brdfcorr.fit.identifiability.CORRELATION_LIMIT`
        Warn with :class:`NonIdentifiableWarning` when a parameter's global correlation
        coefficient [-] (its correlation with the best linear combination of all the others, as
        in MINUIT) exceeds this.
    """

    scale_errors: bool | None = None
    correlation_limit: float = CORRELATION_LIMIT


@dataclass(frozen=True, eq=False)
class _Problem:
    """The bounded weighted least-squares problem of :func:`fit_brdf`.

    Attributes
    ----------
    model : Model
        The registry model.
    geometry : ScatteringGeometry
        The measurements' geometry, computed once.
    data : numpy.ndarray
        Measured BRDF [sr^-1].
    weights : numpy.ndarray
        ``1 / sigma`` [sr] (ones for an unweighted fit [-]).
    fixed : dict of str to float
        Values of the fixed parameters (validated).
    free : tuple of str
        Names of the free parameters in signature order.
    lower, upper : numpy.ndarray
        The optimizer's closed bounds of the free parameters.
    """

    model: Model
    geometry: ScatteringGeometry
    data: np.ndarray
    weights: np.ndarray
    fixed: dict[str, float]
    free: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def weighted_residuals(self, x: np.ndarray) -> np.ndarray:
        """``(model - measured) / sigma`` at the free parameter values ``x`` [-]; a huge finite
        value where the model overflows, so that the optimizer can back off."""
        with np.errstate(all="ignore"):
            values = self.model.kernel(self.geometry, **self.fixed, **dict(zip(self.free, x)))
            residuals = (np.asarray(values, dtype=float) - self.data) * self.weights
        return np.where(np.isfinite(residuals), residuals, _NON_FINITE_RESIDUAL)

    @functools.cached_property
    def _columns(self) -> ScatteringGeometry:
        """The measurements' geometry as (N, 1) columns, against which a row of parameter values
        broadcasts."""
        return ScatteringGeometry(*(np.asarray(angle)[:, None] for angle in
                                    (self.geometry.theta_i, self.geometry.theta_r, self.geometry.phi)))

    def residual_rows(self, _function, points) -> np.ndarray:
        """:meth:`weighted_residuals` at many values of the free parameters at once: one row (N,)
        per point, from one model evaluation over (N, points) (the models are elementwise, so each
        row is what :meth:`weighted_residuals` gives at its point, value for value).

        The ``workers`` map of :func:`scipy.optimize.least_squares`, which evaluates the points of
        a finite-difference Jacobian through it (``workers(function, points)``; ``function`` is
        :meth:`weighted_residuals` as scipy wraps it, computed here in one pass instead).
        """
        values = np.array(list(points), dtype=float)  # (Y, P)
        with np.errstate(all="ignore"):
            model = self.model.kernel(self._columns, **self.fixed, **dict(zip(self.free, values.T)))
            model = np.broadcast_to(np.asarray(model, dtype=float), (self.data.size, len(values)))
            residuals = (model - self.data[:, None]) * self.weights[:, None]
        return np.where(np.isfinite(residuals), residuals, _NON_FINITE_RESIDUAL).T


def _inside(default: float, low: float, high: float) -> float:
    """The start nearest ``default`` a step inside ``[low, high]``: the step is ``max(|default|, 1)``,
    or half the interval where that is narrower (its midpoint). A bound that is infinite or huge
    (-1e308) then leaves the start near the finite end, not at an infinite or absurd midpoint."""
    with np.errstate(over="ignore"):
        step = min(max(abs(default), 1.0), 0.5 * (high - low))
    return low + step if default <= low else high - step


def _starting_points(problem: _Problem, initial: Mapping[str, float]) -> list[np.ndarray]:
    """Deterministic starting vectors for the non-linear fit.

    Scale parameters (registry range open at 0: w, n, c, sigma) without a user starting value
    (``initial``) are stepped over a multiplicative grid around their default (5 values for the
    first, 3 for the others); for each grid point the parameters that enter linearly (t0, t1, a)
    are solved by bounded linear least squares, so every start already matches the data's level
    and peak height.
    """
    model, geometry, data, weights = problem.model, problem.geometry, problem.data, problem.weights
    fixed, free, lower, upper = problem.fixed, problem.free, problem.lower, problem.upper
    centre = {name: initial.get(name, model.parameter(name).default) for name in free}
    for index, name in enumerate(free):  # keep defaults strictly inside user-narrowed bounds
        if name not in initial and not lower[index] < centre[name] < upper[index]:
            centre[name] = _inside(centre[name], lower[index], upper[index])
    candidates = [name for name in free if name not in initial]
    linear = [name for name in model.linear if name in candidates]
    gridded = [
        name for name in candidates
        if name not in linear
        and model.parameter(name).lower == 0.0
        and model.parameter(name).lower_open
    ]
    grids = [_FIRST_GRID if position == 0 else _OTHER_GRID for position in range(len(gridded))]
    starts = []
    for factors in itertools.product(*grids):
        values = dict(centre)
        for name, factor in zip(gridded, factors):
            index = free.index(name)
            values[name] = float(np.clip(factor * centre[name], lower[index], upper[index]))
        if linear:
            # f = sum_j p_j B_j: the linear parameters enter through the model's basis functions;
            # those held fixed (or given a start) contribute a known part.
            shape = {**fixed, **values}
            with np.errstate(all="ignore"):
                terms = dict(zip(model.linear, model.terms(geometry, shape)))
                known = sum(
                    (shape[name] * np.asarray(term, dtype=float) for name, term in terms.items() if name not in linear),
                    np.zeros_like(data),
                )
                design = np.column_stack([np.broadcast_to(np.asarray(terms[name], dtype=float), data.shape)
                                          for name in linear])
            if np.all(np.isfinite(design)) and np.all(np.isfinite(known)):
                indices = [free.index(name) for name in linear]
                solution = lsq_linear(
                    design * weights[:, None], (data - known) * weights,
                    bounds=(lower[indices], upper[indices]),
                )
                values.update(zip(linear, solution.x))
        starts.append(np.clip([values[name] for name in free], lower, upper))
    return starts


def fit_brdf(model, theta_i, theta_r, phi, brdf, sigma=None, fixed: Mapping[str, float] | None = None,
             initial: Mapping[str, float] | None = None, bounds: Mapping[str, tuple[float, float]] | None = None, *,
             error_analysis: ErrorAnalysis = ErrorAnalysis()) -> FitResult:
    """Fit a BRDF model to measurements by weighted least squares (paper 003, section 4).

    Parameters
    ----------
    model : str or Model
        Registry model name (``"torrance_sparrow"``) or model.
    theta_i, theta_r : array-like
        Illumination and view zenith angles of the measurements [deg], in [0, 90).
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.
    brdf : array-like
        Measured BRDF [sr^-1], >= 0.
    sigma : array-like, optional
        1-sigma measurement errors [sr^-1], > 0; the weights are 1 / sigma^2. None: unit weights.
    fixed : mapping, optional
        Parameters held at a given value, e.g. ``{"k": 0.25}`` as in paper 003.
    initial : mapping, optional
        Starting values of free parameters, tried first. In any case the fit also starts from a
        grid: the scale parameters (w, n, ...) at multiples of their registry default, the
        amplitudes (t0, t1, a) from a linear least-squares solution at each grid point, the other
        parameters at their defaults. The lowest chi^2 of all starts wins. A start must lie in
        the parameter's physical range and its ``bounds``; one above an open lower bound but
        below the optimizer's floor there (``0 < w < OPEN_BOUND_FLOOR`` of the default) starts at
        the floor.
    bounds : mapping of (lower, upper), optional
        Narrower bounds for free parameters, intersected with the registry's physical range
        (the default; open lower bounds such as w > 0 become ``OPEN_BOUND_FLOOR`` of the default).
    error_analysis : ErrorAnalysis, default ErrorAnalysis()
        How the covariance is estimated (by default: from ``sigma``; without it the
        heteroscedasticity-robust HC3 sandwich of the residuals, scaled by chi^2/dof only where
        that is undefined) and from which global correlation on a parameter counts as not
        identifiable.

    Returns
    -------
    FitResult

    Raises
    ------
    brdfcorr.errors.MeasurementError
        Invalid measurements (see :func:`brdfcorr.fit.measurements.check_measurements`).
    brdfcorr.errors.ParameterError
        Unknown parameter names, invalid fixed values, empty bounds.
    brdfcorr.errors.FitError
        Nothing to fit, not more measurements than free parameters, or no start converged (and
        fewer than two ran out of evaluations at one chi^2, :func:`_best_solution`).

    Warns
    -----
    NonIdentifiableWarning
        A parameter with a global correlation beyond ``error_analysis.correlation_limit``, a
        parameter whose error exceeds both its value and its default, or an ill-conditioned or
        singular Jacobian (paper 003: n, k and t1 trade off unless k is fixed).
    FitWarning
        A free parameter ended on a bound, or the fit lies at a limit of the model (no start
        converged, several ran out of evaluations at one chi^2: :func:`_best_solution`).
    AlbedoWarning
        The fitted model's albedo (directional-hemispherical reflectance) exceeds 1 at a measured
        illumination zenith: the measurements are likely in percent or reflectance factors
        (pi * BRDF). Not one of the result's ``warnings``: it says nothing about the errors.

    Notes
    -----
    Minimizes paper 003's eq. 4, ``chi^2 = sum((f_measured - f_model)^2 / sigma^2)``, with
    :func:`scipy.optimize.least_squares` (trust-region reflective, bounded) on a
    :class:`~brdfcorr.geometry.ScatteringGeometry` computed once. Each starting point (see
    ``initial``) is optimized and the lowest chi^2 kept. The covariance is ``(J^T J)^-1`` with J the
    Jacobian of the weighted residuals at the minimum, i.e. the errors of the linearized (first
    order Taylor-expanded) model of Brandt [2]_; Press et al. [3]_ give the same recipe. As paper 003
    warns, these errors are rough for strongly non-linear parameters with large errors (n, k).
    """
    problem, sigma, initial = _problem(get_model(model), (theta_i, theta_r, phi, brdf, sigma), fixed, initial, bounds)
    starts = _starting_points(problem, initial)
    if initial:  # the user's start first, then the default grid: a poor guess cannot spoil the fit
        starts += _starting_points(problem, {})
    result = _result(problem, sigma, starts, error_analysis)
    excess = albedo_excess(problem.model.name, result.predict, problem.geometry.theta_i)
    if excess:  # no surface reflects more than it receives: percent or pi * BRDF given as BRDF?
        warnings.warn(excess, AlbedoWarning, stacklevel=2)
    return result


def fit_from(model, theta_i, theta_r, phi, brdf, sigma=None, *, start: Mapping[str, float],
             fixed: Mapping[str, float] | None = None,
             bounds: Mapping[str, tuple[float, float]] | None = None) -> FitResult:
    """:func:`fit_brdf` from ``start`` alone, without the grid of starts: one local optimization
    where it gives every free parameter (another fit's values: a cross-validation fold's fit from
    the fit to all the measurements, :func:`brdfcorr.fit.selection.choose_model`). Arguments and
    errors as for :func:`fit_brdf`; a start that does not converge is a
    :class:`~brdfcorr.errors.FitError` (a fit at a limit of the model needs several starts)."""
    problem, sigma, start = _problem(get_model(model), (theta_i, theta_r, phi, brdf, sigma), fixed, start, bounds)
    return _result(problem, sigma, _starting_points(problem, start), ErrorAnalysis())


def _result(problem: _Problem, sigma, starts: list[np.ndarray], error_analysis: ErrorAnalysis) -> FitResult:
    """The :class:`FitResult` of the best solution from ``starts`` (:func:`_best_solution`), with its
    covariance, goodness of fit and warnings (:func:`fit_brdf`)."""
    model, data, free = problem.model, problem.data, problem.free
    best, n_converged, limit, solutions = _best_solution(problem, starts)
    values = dict(zip(free, map(float, best.x)))
    model_values = np.asarray(model.kernel(problem.geometry, **problem.fixed, **values), dtype=float)
    residuals = data - model_values
    chi2, r2 = _goodness(data, residuals, problem.weights)
    dof = data.size - len(free)
    covariance, condition_number = jacobian_covariance(best.jac)
    by_default = sigma is None and error_analysis.scale_errors is None  # robust where it can be
    unrobust = robust_problem(best.jac, covariance, dof) if by_default else None
    robust = by_default and unrobust is None and bool(np.all(np.isfinite(covariance)))
    if robust:
        covariance = hc3_covariance(best.jac, residuals * problem.weights, covariance)
    scale_errors = bool(error_analysis.scale_errors) or (by_default and not robust)
    if scale_errors:
        covariance = covariance * (chi2 / dof)
    minima = other_minima(best, solutions, chi2 / dof, weighted=sigma is not None)
    messages, at_bounds = _fit_warnings(problem, values, best.active_mask, covariance, condition_number,
                                        error_analysis.correlation_limit, minima)
    if unrobust is not None:
        messages.append(f"{model.name}: {unrobust}")
        warnings.warn(messages[-1], FitWarning, stacklevel=3)
    if limit:
        messages.append(_limit_message(problem, values, n_converged))
        warnings.warn(messages[-1], FitWarning, stacklevel=3)
    all_values, errors = _parameter_values(problem, values, np.sqrt(np.diag(covariance)))
    return FitResult(
        model=model, params=all_values, errors=errors, free=free, fixed=problem.fixed, covariance=covariance,
        correlation=correlation_matrix(covariance), chi2=chi2, dof=dof, residuals=residuals, sigma=sigma,
        errors_scaled=scale_errors, errors_robust=robust,
        condition_number=condition_number, at_bounds=at_bounds,
        n_starts=len(starts), n_converged=n_converged, warnings=tuple(messages), r2=r2,
    )


def _problem(model: Model, measurements: tuple, fixed, initial, bounds):
    """The least-squares problem of :func:`fit_brdf` from its arguments.

    ``measurements`` are (theta_i, theta_r, phi [deg], brdf, sigma [sr^-1] or None), checked by
    :func:`~brdfcorr.fit.measurements.check_measurements`; ``fixed``, ``initial`` and ``bounds`` as
    for :func:`fit_brdf` (:func:`_free_parameters`). Returns the :class:`_Problem`, the checked
    sigma (None: unweighted) and the user's starting values (a dict). Raises :class:`FitError`
    when there are not more measurements than free parameters.
    """
    theta_i, theta_r, phi, data, sigma = check_measurements(*measurements)
    fixed, free, lower, upper, initial = _free_parameters(model, fixed, initial, bounds)
    if data.size <= len(free):
        raise FitError(
            f"{model.name}: {data.size} measurements cannot determine {len(free)} free parameters "
            f"({', '.join(free)}); at least {len(free) + 1} are needed"
        )
    weights = np.ones_like(data) if sigma is None else 1.0 / sigma
    problem = _Problem(model, ScatteringGeometry(theta_i, theta_r, phi), data, weights, fixed, free, lower, upper)
    return problem, sigma, initial


#: Starts that ran out of evaluations count as a fit at a limit of the model (:func:`_best_solution`)
#: when at least this many reached the same chi^2: within :data:`LIMIT_AGREEMENT` of its share per
#: degree of freedom (chi^2 / dof), far below what the measurements can tell apart.
LIMIT_STARTS, LIMIT_AGREEMENT = 2, 0.01


def _best_solution(problem: _Problem, starts: list[np.ndarray]):
    """Least squares (trust-region reflective, within the bounds) from every start.

    Returns the solution with the lowest cost (:class:`scipy.optimize.OptimizeResult`), how many
    starts reached it (within 1e-6 relative) and whether it is a fit at a limit of the model: where
    no start converged but :data:`LIMIT_STARTS` or more ran out of evaluations at the same cost
    (within :data:`LIMIT_AGREEMENT` of chi^2 / dof), their best is kept; they followed a valley towards an optimum
    the model reaches only in a limit (RPV on a specular lobe: theta -> 1 with rho0 -> inf, where
    ``rho0 (1 - theta^2)`` stays finite), so the cost is the infimum but the parameters are not
    determined. Raises :class:`FitError` when neither happened.
    """
    solutions, exhausted = [], []
    for start in starts:
        try:
            solution = least_squares(
                problem.weighted_residuals, start, bounds=(problem.lower, problem.upper), x_scale="jac",
                method="trf", workers=problem.residual_rows,  # the Jacobian's points in one model call
            )
        except (ValueError, np.linalg.LinAlgError):  # a start where the model is not finite
            continue
        if np.isfinite(solution.cost):
            (solutions if solution.status > 0 else exhausted if solution.status == 0 else []).append(solution)
    tolerance, limit = 1e-6, not solutions
    if limit:
        tolerance = LIMIT_AGREEMENT / max(problem.data.size - len(problem.free), 1)
        solutions = _agreeing(exhausted, tolerance)
        if len(solutions) < LIMIT_STARTS:
            raise FitError(f"{problem.model.name}: the fit did not converge from any of {len(starts)} starts")
    best = min(solutions, key=lambda solution: solution.cost)
    return best, len(_agreeing(solutions, tolerance)), limit, solutions


def _agreeing(solutions: list, tolerance: float) -> list:
    """The solutions whose cost is within ``tolerance`` (relative) of the lowest."""
    if not solutions:
        return []
    lowest = min(solution.cost for solution in solutions)
    return [solution for solution in solutions if solution.cost <= lowest * (1 + tolerance) + 1e-300]


def _limit_message(problem: _Problem, values: Mapping[str, float], n_agreeing: int) -> str:
    """The warning of a fit at a limit of the model (:func:`_best_solution`), naming the free
    parameters within 1 % of a finite bound."""
    near = [f"{name} = {values[name]:.4g}" for name, low, high in zip(problem.free, problem.lower, problem.upper)
            if math.isfinite(high - low) and min(values[name] - low, high - values[name]) < 0.01 * (high - low)]
    where = f" (towards {', '.join(near)} at the end of its range)" if near else ""
    return (f"{problem.model.name}: no start converged; {n_agreeing} ran out of evaluations at the same chi^2 "
            f"along a valley{where}: the best fit lies at a limit of the model, its parameters and errors "
            "are not determined (another model may describe the surface)")


def _goodness(data: np.ndarray, residuals: np.ndarray, weights: np.ndarray) -> tuple[float, float]:
    """chi^2 ``sum((residuals * weights)^2)`` ([-]; [sr^-2] with unit weights) and the unweighted
    R^2 of the measurements (NaN when they are all equal)."""
    chi2 = float(np.sum((residuals * weights) ** 2))
    spread = float(np.sum((data - data.mean()) ** 2))
    r2 = 1.0 - float(np.sum(residuals**2)) / spread if spread > 0 else math.nan
    return chi2, r2


def _parameter_values(problem: _Problem, values: Mapping[str, float], deviations: np.ndarray):
    """All parameters in the model's signature order, the fitted ``values`` and the fixed ones, and
    their 1-sigma errors (``deviations`` of the free parameters, 0.0 for the fixed ones): two dicts."""
    names = problem.model.parameter_names
    params = {name: values.get(name, problem.fixed.get(name)) for name in names}
    errors = {
        name: float(deviations[problem.free.index(name)]) if name in values else 0.0
        for name in names
    }
    return params, errors


def _fit_warnings(problem: _Problem, values, active_mask, covariance, condition_number, correlation_limit, others):
    """Warn, as from the caller of :func:`fit_brdf`, with :class:`NonIdentifiableWarning` for what
    the measurements cannot separate (:func:`~brdfcorr.fit.identifiability.identifiability_messages`
    of the ``covariance`` and ``condition_number`` at the fitted ``values``, ``correlation_limit``)
    and with :class:`FitWarning` for free parameters that ended on a bound (``active_mask`` of the
    solution). Returns the messages (a list) and the parameters at a bound (a tuple).
    """
    model, free = problem.model, problem.free
    messages = identifiability_messages(model, free, values, covariance, condition_number, correlation_limit, others)
    for message in messages:
        warnings.warn(message, NonIdentifiableWarning, stacklevel=4)
    at_bounds = tuple(name for name, active in zip(free, active_mask) if active != 0)
    if at_bounds:
        message = (
            f"{model.name}: parameter(s) {', '.join(at_bounds)} ended on a bound "
            f"({', '.join(f'{name} = {values[name]:.4g}' for name in at_bounds)}); "
            "their errors are not meaningful"
        )
        messages.append(message)
        warnings.warn(message, FitWarning, stacklevel=4)
    return messages, at_bounds


def fit_measurements(model, measurements: Measurements, **kwargs) -> FitResult:
    """:func:`fit_brdf` on a :class:`~brdfcorr.fit.measurements.Measurements` table (its sigma, if any,
    as weights). Keyword arguments are passed on (``fixed``, ``initial``, ``bounds``, ...)."""
    return fit_brdf(
        model,
        measurements.theta_i,
        measurements.theta_r,
        measurements.phi,
        measurements.brdf,
        measurements.sigma,
        **kwargs,
    )


def fit_wavelengths(model, measurements: Measurements, **kwargs) -> dict[float, FitResult]:
    """Fit every wavelength of a multi-wavelength measurement table separately.

    Parameters
    ----------
    model : str or Model
        Registry model name or model.
    measurements : Measurements
        With a ``wavelength`` column [nm].
    **kwargs
        Passed to :func:`fit_brdf` for every wavelength (``fixed``, ``initial``, ``bounds``, ...).

    Returns
    -------
    dict of float to FitResult
        By wavelength [nm], increasing. Warnings of each fit name the wavelength.
    """
    if measurements.wavelength is None:
        raise FitError(f"{measurements.source}: the measurements have no wavelength column")
    results = {}
    for wavelength in measurements.wavelengths:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", FitWarning)
            results[wavelength] = fit_measurements(model, measurements.at_wavelength(wavelength), **kwargs)
        for warning in caught:
            warnings.warn(f"{wavelength:.10g} nm: {warning.message}", warning.category, stacklevel=2)
    return results

