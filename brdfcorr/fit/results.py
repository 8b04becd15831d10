"""The result of a goniometer fit and the parameter-table entries and report rows made from it.

:class:`FitResult` holds what :func:`brdfcorr.fit.goniometer.fit_brdf` found (parameters, 1-sigma
errors, covariance, chi^2, ...) and turns it into one class of a parameter table
(:meth:`FitResult.table_entry`, with the ``fit:`` provenance block of :meth:`FitResult.fit_record`)
or one row of a table like paper 003, Table 1 (:meth:`FitResult.summary`, values quoted by
:func:`format_with_error`). :func:`spectral_table_entry` makes one table class of the fits of
several wavelengths (:func:`brdfcorr.fit.goniometer.fit_wavelengths`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtrc  # chi2's survival function; scipy.stats costs ~1.7 s to import

from brdfcorr.errors import FitError
from brdfcorr.fit.identifiability import global_correlation
from brdfcorr.models import Model

__all__ = ["FitResult", "format_with_error", "spectral_table_entry"]


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
    errors_robust : bool
        Whether the covariance is the heteroscedasticity-robust (HC3) sandwich of the residuals (an
        unweighted fit; :class:`~brdfcorr.fit.goniometer.ErrorAnalysis`).
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
    errors_robust: bool = False
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
        return float(chdtrc(self.dof, self.chi2))

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

    @property
    def errors_reason(self) -> str:
        """Why the errors cannot be trusted (empty when they can): a singular covariance, and the
        fit's warnings (parameters the measurements do not separate, parameters that ended on a
        bound, whose sampling distribution is cut off)."""
        reasons = [] if np.all(np.isfinite(self.covariance)) else ["singular covariance"]
        return "; ".join([*reasons, *self.warnings])

    @property
    def errors_reliable(self) -> bool:
        """Whether the errors can be trusted (:attr:`errors_reason` is empty)."""
        return not self.errors_reason

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
            "errors_reliable": self.errors_reliable,
            "errors_reason": self.errors_reason or None,
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
            "errors_reliable": all(record["errors_reliable"] for record in records),
            "errors_reason": "; ".join(f"{wavelength:g} nm: {record['errors_reason']}" for wavelength, record
                                       in zip(wavelengths, records) if record["errors_reason"]) or None,
        }
    return entry
