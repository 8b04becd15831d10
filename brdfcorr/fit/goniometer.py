"""Fit BRDF models to goniometer measurements by weighted least squares, as paper 003 did.

:func:`fit_brdf` fits any model of the registry (:mod:`brdfcorr.models`) to BRDF measurements
with :func:`scipy.optimize.least_squares`, holding any subset of the parameters fixed (paper 003
fixes k = 0.25), within the registry's physical bounds, from several deterministic starting points.
It returns a :class:`FitResult` with 1-sigma errors from the covariance matrix, chi^2, the degrees
of freedom, the residuals and the parameter correlations, and warns with
:class:`NonIdentifiableWarning` when the measurements cannot separate the parameters (paper 003,
section 4: n, k and t1 trade off).

The helpers that turn a model and a user's ``fixed``/``initial``/``bounds`` into a bounded problem
(:func:`_free_parameters`) and that find starting values (:func:`_starting_points`) do not depend
on where the measurements come from. The covariance, correlations and identifiability messages
live in :mod:`brdfcorr.fit.identifiability`.

References
----------
.. [1] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII (``seeds/003``), section 4, eq. 4 and Table 1.
.. [2] S. Brandt (1992): Datenanalyse. BI-Wissenschaftsverlag, p. 276 (errors of a non-linear
   least-squares fit from the linearized model, i.e. the inverse of J^T W J).
.. [3] W. H. Press et al. (2007): Numerical Recipes, 3rd ed., section 15.4-15.5 (chi^2 fitting,
   covariance from the design matrix, scaling by chi^2/dof when the errors are unknown).
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, lsq_linear
from scipy.stats import chi2 as chi2_distribution

from brdfcorr.errors import BrdfcorrWarning, FitError, ParameterError
from brdfcorr.fit.identifiability import (
    CONDITION_LIMIT,  # noqa: F401  (importable from here as before the split)
    CORRELATION_LIMIT,
    correlation_matrix,
    global_correlation,
    identifiability_messages,
    jacobian_covariance,
)
from brdfcorr.fit.measurements import Measurements, check_measurements
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import Model, get_model

__all__ = [
    "FitResult",
    "FitWarning",
    "NonIdentifiableWarning",
    "fit_brdf",
    "fit_measurements",
    "fit_wavelengths",
    "spectral_table_entry",
    "format_with_error",
]

#: Open lower bounds (w > 0, n > 0) become ``lower + OPEN_BOUND_FLOOR * default`` for the optimizer,
#: which needs closed bounds; 1e-6 of a typical value is far below any meaningful fit.
OPEN_BOUND_FLOOR = 1e-6
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


@dataclass(frozen=True, eq=False)
class FitResult:
    """The result of a least-squares BRDF model fit.

    Attributes
    ----------
    model : Model
        The fitted registry model.
    params : dict of str to float
        All parameters in the model's signature order: fitted values and the fixed ones.
    errors : dict of str to float
        1-sigma errors of ``params`` from :attr:`covariance` (0.0 for fixed parameters, inf where
        the covariance is singular). See :func:`fit_brdf` for how they are scaled.
    free : tuple of str
        Names of the fitted parameters: the order of the rows of :attr:`covariance`.
    fixed : dict of str to float
        The parameters held fixed.
    covariance : numpy.ndarray
        Covariance matrix of the free parameters, shape ``(len(free), len(free))``, in the
        parameters' units squared.
    correlation : numpy.ndarray
        Correlation matrix of the free parameters (``covariance`` normalized by its diagonal).
    chi2 : float
        ``sum(((measured - model) / sigma)^2)`` (paper 003, eq. 4); without sigma the plain sum of
        squared residuals [sr^-2].
    dof : int
        Degrees of freedom: measurements minus free parameters.
    residuals : numpy.ndarray
        ``measured - model`` for every measurement [sr^-1].
    sigma : numpy.ndarray or None
        The measurement errors used as weights [sr^-1] (None for an unweighted fit).
    errors_scaled : bool
        Whether the covariance was multiplied by ``chi2 / dof``.
    condition_number : float
        Condition number of the Jacobian with unit-norm columns (1 is ideal; large values mean some
        parameter combination is barely constrained).
    at_bounds : tuple of str
        Free parameters that ended on a bound (their errors are not meaningful).
    n_starts : int
        Number of starting points tried.
    n_converged : int
        Number of starts that reached the best chi^2 (within 1e-6 relative); a small fraction
        means a multi-modal chi^2 surface.
    r2 : float
        Coefficient of determination of the measurements, ``1 - sum(r^2) / sum((f - mean f)^2)``
        (unweighted; NaN when the measurements are all equal).
    """

    model: Model
    params: dict[str, float]
    errors: dict[str, float]
    free: tuple[str, ...]
    fixed: dict[str, float]
    covariance: np.ndarray
    correlation: np.ndarray
    chi2: float
    dof: int
    residuals: np.ndarray
    sigma: np.ndarray | None
    errors_scaled: bool
    condition_number: float
    at_bounds: tuple[str, ...] = ()
    n_starts: int = 1
    n_converged: int = 1
    warnings: tuple[str, ...] = field(default=())
    r2: float = math.nan

    @property
    def reduced_chi2(self) -> float:
        """chi^2 per degree of freedom (the chi^2/d_f of paper 003, Table 1)."""
        return self.chi2 / self.dof if self.dof > 0 else math.nan

    @property
    def n_measurements(self) -> int:
        return self.residuals.size

    @property
    def p_value(self) -> float:
        """Probability of a chi^2 at least this large if the model and the errors were right
        (the chi^2 test of paper 003; NaN for an unweighted fit, whose chi^2 has units)."""
        if self.sigma is None or self.dof <= 0:
            return math.nan
        return float(chi2_distribution.sf(self.chi2, self.dof))

    @property
    def pulls(self) -> np.ndarray:
        """Residuals in units of their errors, ``(measured - model) / sigma`` [-]."""
        return self.residuals if self.sigma is None else self.residuals / self.sigma

    @property
    def global_correlation(self) -> dict[str, float]:
        """Each free parameter's global correlation coefficient with all the others [-]: 0 when it
        is independent, 1 when the others can fully compensate a change of it (MINUIT's
        ``sqrt(1 - 1 / (V_jj (V^-1)_jj))``)."""
        if not np.all(np.isfinite(self.covariance)):
            return {name: math.nan for name in self.free}
        return dict(zip(self.free, map(float, global_correlation(self.covariance))))

    def correlation_of(self, first: str, second: str) -> float:
        """Correlation coefficient of two free parameters."""
        return float(self.correlation[self.free.index(first), self.free.index(second)])

    def predict(self, theta_i, theta_r, phi):
        """The fitted model's BRDF [sr^-1] at the given angles [deg] (numpy, dask or xarray)."""
        return self.model(theta_i, theta_r, phi, **self.params)

    def table_entry(self, class_id: int, name: str, source: str | None = None) -> dict:
        """The fit as one class of a parameter table (``docs/parameter-tables.md`` format), for
        :meth:`brdfcorr.params.ParameterTable.with_class`; values as plain floats.

        With ``source`` (what was fitted: the command and its input file) the entry carries the
        ``fit:`` provenance block (:meth:`fit_record`), unless the covariance is singular.
        """
        entry = {
            "id": int(class_id),
            "name": str(name),
            "model": self.model.name,
            "params": {key: float(value) for key, value in self.params.items()},
        }
        record = None if source is None else self.fit_record(source)
        if record is not None:
            entry["fit"] = record
        return entry

    def fit_record(self, source: str) -> dict | None:
        """The ``fit:`` block of a parameter table (:class:`brdfcorr.params.FitRecord`): the free
        parameters, their covariance and 1-sigma errors, N, chi^2/dof and R^2. None when the
        covariance is not finite (a singular Jacobian): a table holds numbers only."""
        covariance = _symmetric(self.covariance)
        if covariance is None:
            return None
        return {
            "source": str(source),
            "parameters": list(self.free),
            "n": int(self.n_measurements),
            "chi2_dof": float(self.reduced_chi2),
            "r2": float(self.r2),
            "errors": dict(zip(self.free, np.sqrt(np.diag(covariance)).tolist())),
            "covariance": covariance.tolist(),
        }

    def summary(self) -> dict[str, str]:
        """One row of a table like paper 003, Table 1: ``"value ± error"`` per parameter (with
        units in the keys) and chi^2/dof."""
        row = {}
        for parameter in self.model.parameters:
            name, value = parameter.name, self.params[parameter.name]
            key = name if parameter.units == "1" else f"{name} [{parameter.units}]"
            row[key] = (
                f"{value:.4g} (fixed)" if name in self.fixed
                else format_with_error(value, self.errors[name])
            )
        row["chi2/dof"] = f"{self.reduced_chi2:.3g}"
        return row


def _symmetric(covariance: np.ndarray) -> np.ndarray | None:
    """A covariance made exactly symmetric for a table, or None if it is not finite or has a
    negative variance."""
    covariance = np.asarray(covariance, dtype=float)
    if not np.all(np.isfinite(covariance)) or np.any(np.diag(covariance) < 0):
        return None
    return 0.5 * (covariance + covariance.T)


def format_with_error(value: float, error: float) -> str:
    """``value ± error`` with the error rounded to 1-2 significant digits and the value to match.

    Two digits when the error's leading digit is 1 or 2 (0.0012, 0.25), one otherwise (0.0004,
    0.3), the usual convention for quoting measurement errors.
    """
    if not math.isfinite(error) or error <= 0:
        return f"{value:.4g} ± {error:g}"
    mantissa, exponent = f"{error:.3e}".split("e")  # decimal digits, free of binary rounding
    exponent = int(exponent)
    digits = 2 if float(mantissa) < 3.0 else 1
    decimals = -(exponent - digits + 1)
    rounded = round(error, decimals)
    if rounded >= 10 ** (exponent + 1) and digits == 1:  # 0.96 -> 1.0: keep one digit
        decimals -= 1
    if decimals > 0:
        return f"{value:.{decimals}f} ± {error:.{decimals}f}"
    return f"{round(value, decimals):.0f} ± {round(error, decimals):.0f}"


def _scalar(value, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{what} must be a single number, got {value!r}") from None
    if not math.isfinite(number):
        raise ParameterError(f"{what} must be finite, got {number!r}")
    return number


def _free_parameters(model: Model, fixed, initial, bounds):
    """Split the model's parameters into fixed values and bounded free ones.

    Returns ``(fixed, free, lower, upper, start)``: fixed values (validated), free names in
    signature order, the optimizer's closed bounds and the user's starting values (a dict).
    """
    fixed = {name: value for name, value in dict(fixed or {}).items()}
    initial = dict(initial or {})
    bounds = dict(bounds or {})
    for name in itertools.chain(fixed, initial, bounds):
        model.parameter(name)  # unknown name -> ParameterError naming the model's parameters
    for name, value in fixed.items():
        model.parameter(name).check(value, f"{model.name} (fixed)")
        fixed[name] = _scalar(value, f"{model.name}: fixed value of {name}")
    both = sorted(set(fixed) & (set(initial) | set(bounds)))
    if both:
        raise ParameterError(
            f"{model.name}: parameter(s) {', '.join(both)} are fixed and cannot also have a "
            "starting value or bounds"
        )
    free = tuple(name for name in model.parameter_names if name not in fixed)
    if not free:
        raise FitError(f"{model.name}: every parameter is fixed; nothing to fit")

    lower, upper = [], []
    for name in free:
        parameter = model.parameter(name)
        low, high = parameter.lower, parameter.upper
        if parameter.lower_open:
            low = low + OPEN_BOUND_FLOOR * max(abs(parameter.default), 1e-3)
        if name in bounds:
            try:
                user_low, user_high = (float(value) for value in bounds[name])
            except (TypeError, ValueError):
                raise ParameterError(
                    f"{model.name}: bounds of {name} must be a pair (lower, upper), got {bounds[name]!r}"
                ) from None
            low, high = max(low, user_low), min(high, user_high)
            if not low < high:
                raise ParameterError(
                    f"{model.name}: bounds of {name} ({user_low:g}, {user_high:g}) leave no room "
                    f"within its physical range {parameter.range_text} [{parameter.units}]"
                )
        lower.append(low)
        upper.append(high)
    for name, value in initial.items():
        index = free.index(name)
        value = _scalar(value, f"{model.name}: starting value of {name}")
        if not lower[index] <= value <= upper[index]:
            raise ParameterError(
                f"{model.name}: starting value {name} = {value:g} is outside its bounds "
                f"[{lower[index]:g}, {upper[index]:g}]"
            )
        initial[name] = value
    return fixed, free, np.array(lower), np.array(upper), initial


def _starting_points(model, geometry, data, weights, fixed, free, lower, upper, initial):
    """Deterministic starting vectors for the non-linear fit.

    Scale parameters (registry range open at 0: w, n, c, sigma) without a user starting value are
    stepped over a multiplicative grid around their default (5 values for the first, 3 for the
    others); for each grid point the parameters that enter linearly (t0, t1, a) are solved by
    bounded linear least squares, so every start already matches the data's level and peak height.
    """
    centre = {name: initial.get(name, model.parameter(name).default) for name in free}
    for index, name in enumerate(free):  # keep defaults strictly inside user-narrowed bounds
        if name not in initial and not lower[index] < centre[name] < upper[index]:
            finite_upper = upper[index] if math.isfinite(upper[index]) else lower[index] + 1.0
            centre[name] = 0.5 * (lower[index] + finite_upper)
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


def fit_brdf(
    model,
    theta_i,
    theta_r,
    phi,
    brdf,
    sigma=None,
    fixed: Mapping[str, float] | None = None,
    initial: Mapping[str, float] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    *,
    scale_errors: bool | None = None,
    correlation_limit: float = CORRELATION_LIMIT,
) -> FitResult:
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
        parameters at their defaults. The lowest chi^2 of all starts wins.
    bounds : mapping of (lower, upper), optional
        Narrower bounds for free parameters, intersected with the registry's physical range
        (the default; open lower bounds such as w > 0 become ``OPEN_BOUND_FLOOR`` of the default).
    scale_errors : bool, optional
        Multiply the covariance by chi^2/dof. Default: only when ``sigma`` is None, so that the
        errors of an unweighted fit are estimated from the scatter of the residuals. With
        ``sigma`` given the errors are those implied by the measurement errors alone (Brandt [2]_,
        as in paper 003, Table 1) and chi^2/dof says separately how well the model fits; a
        chi^2/dof well above 1 means the errors are too small by about sqrt(chi^2/dof).
    correlation_limit : float
        Warn with :class:`NonIdentifiableWarning` when a parameter's global correlation
        coefficient (its correlation with the best linear combination of all the others, as in
        MINUIT) exceeds this.

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
        Nothing to fit, not more measurements than free parameters, or no start converged.

    Warns
    -----
    NonIdentifiableWarning
        A parameter with a global correlation beyond ``correlation_limit``, a parameter whose
        error exceeds both its value and its default, or an ill-conditioned or singular Jacobian
        (paper 003: n, k and t1 trade off unless k is fixed).
    FitWarning
        A free parameter ended on a bound.

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
    model = get_model(model)
    theta_i, theta_r, phi, data, sigma = check_measurements(theta_i, theta_r, phi, brdf, sigma)
    fixed, free, lower, upper, initial = _free_parameters(model, fixed, initial, bounds)
    if data.size <= len(free):
        raise FitError(
            f"{model.name}: {data.size} measurements cannot determine {len(free)} free parameters "
            f"({', '.join(free)}); at least {len(free) + 1} are needed"
        )
    geometry = ScatteringGeometry(theta_i, theta_r, phi)
    weights = np.ones_like(data) if sigma is None else 1.0 / sigma

    def weighted_residuals(x):
        with np.errstate(all="ignore"):
            values = model.kernel(geometry, **fixed, **dict(zip(free, x)))
            residuals = (np.asarray(values, dtype=float) - data) * weights
        return np.where(np.isfinite(residuals), residuals, _NON_FINITE_RESIDUAL)

    starts = _starting_points(model, geometry, data, weights, fixed, free, lower, upper, initial)
    if initial:  # the user's start first, then the default grid: a poor guess cannot spoil the fit
        starts += _starting_points(model, geometry, data, weights, fixed, free, lower, upper, {})
    solutions = []
    for start in starts:
        try:
            solution = least_squares(
                weighted_residuals, start, bounds=(lower, upper), x_scale="jac", method="trf"
            )
        except (ValueError, np.linalg.LinAlgError):  # a start where the model is not finite
            continue
        if solution.status > 0 and np.isfinite(solution.cost):
            solutions.append(solution)
    if not solutions:
        raise FitError(f"{model.name}: the fit did not converge from any of {len(starts)} starts")
    best = min(solutions, key=lambda solution: solution.cost)
    n_converged = sum(
        solution.cost <= best.cost * (1 + 1e-6) + 1e-300 for solution in solutions
    )

    values = dict(zip(free, map(float, best.x)))
    model_values = np.asarray(model.kernel(geometry, **fixed, **values), dtype=float)
    residuals = data - model_values
    chi2 = float(np.sum((residuals * weights) ** 2))
    dof = data.size - len(free)
    spread = float(np.sum((data - data.mean()) ** 2))
    r2 = 1.0 - float(np.sum(residuals**2)) / spread if spread > 0 else math.nan
    covariance, condition_number = jacobian_covariance(best.jac)
    if scale_errors is None:
        scale_errors = sigma is None
    if scale_errors:
        covariance = covariance * (chi2 / dof)
    correlation = correlation_matrix(covariance)
    deviations = np.sqrt(np.diag(covariance))

    messages = identifiability_messages(
        model, free, values, covariance, condition_number, correlation_limit
    )
    for message in messages:
        warnings.warn(message, NonIdentifiableWarning, stacklevel=2)
    at_bounds = tuple(name for name, active in zip(free, best.active_mask) if active != 0)
    if at_bounds:
        message = (
            f"{model.name}: parameter(s) {', '.join(at_bounds)} ended on a bound "
            f"({', '.join(f'{name} = {values[name]:.4g}' for name in at_bounds)}); "
            "their errors are not meaningful"
        )
        messages.append(message)
        warnings.warn(message, FitWarning, stacklevel=2)

    all_values = {name: values.get(name, fixed.get(name)) for name in model.parameter_names}
    errors = {
        name: float(deviations[free.index(name)]) if name in values else 0.0
        for name in model.parameter_names
    }
    return FitResult(
        model=model,
        params=all_values,
        errors=errors,
        free=free,
        fixed=fixed,
        covariance=covariance,
        correlation=correlation,
        chi2=chi2,
        dof=dof,
        residuals=residuals,
        sigma=sigma,
        errors_scaled=bool(scale_errors),
        condition_number=condition_number,
        at_bounds=at_bounds,
        n_starts=len(starts),
        n_converged=int(n_converged),
        warnings=tuple(messages),
        r2=r2,
    )


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
            warnings.warn(f"{wavelength:g} nm: {warning.message}", warning.category, stacklevel=2)
    return results


def spectral_table_entry(
    results: Mapping[float, FitResult], class_id: int, name: str, source: str | None = None
) -> dict:
    """Fits at several wavelengths as one class of a parameter table (``docs/parameter-tables.md`` format).

    Parameters with the same value at every wavelength (the fixed ones) are written as a scalar,
    the others as a list with ``wavelengths`` [nm], which :class:`brdfcorr.params.ParameterTable`
    interpolates linearly to an image's band centres. A single wavelength gives scalars (no
    ``wavelengths``): the paper-003 practice of one fit (550 nm) for every band.

    With ``source`` the entry carries the ``fit:`` block (:meth:`FitResult.fit_record`): one
    covariance matrix, N, chi^2/dof and R^2 per wavelength; none if a covariance is singular.
    """
    wavelengths = sorted(results)
    if not wavelengths:
        raise FitError("no fits to put into a parameter table")
    models = {results[wavelength].model.name for wavelength in wavelengths}
    if len(models) > 1:
        raise FitError(f"fits of different models ({', '.join(sorted(models))}) cannot form one class")
    if len(wavelengths) == 1:
        return results[wavelengths[0]].table_entry(class_id, name, source)
    first = results[wavelengths[0]]
    params = {}
    for parameter in first.model.parameter_names:
        values = [float(results[wavelength].params[parameter]) for wavelength in wavelengths]
        params[parameter] = values[0] if len(set(values)) == 1 else values
    entry = {
        "id": int(class_id),
        "name": str(name),
        "model": first.model.name,
        "wavelengths": [float(wavelength) for wavelength in wavelengths],
        "params": params,
    }
    records = [] if source is None else [results[wavelength].fit_record(source) for wavelength in wavelengths]
    if records and all(record is not None for record in records):
        entry["fit"] = {
            "source": str(source),
            "parameters": list(first.free),
            **{key: [record[key] for record in records] for key in ("n", "chi2_dof", "r2")},
            "errors": {name: [record["errors"][name] for record in records] for name in first.free},
            "covariance": [record["covariance"] for record in records],
        }
    return entry
