"""Whether goniometer measurements determine a model's parameters: covariance from the Jacobian,
correlations, and the identifiability messages of :func:`brdfcorr.fit.goniometer.fit_brdf`.

Paper 003 (section 4) found that n, k and t1 of the Torrance-Sparrow model trade off unless k is
fixed; these diagnostics say so for any model and fit.

References
----------
.. [1] S. Brandt (1992): Datenanalyse. BI-Wissenschaftsverlag, p. 276 (errors of a non-linear
   least-squares fit from the linearized model, i.e. the inverse of J^T W J).
.. [2] F. James, M. Roos (1975): MINUIT. Comput. Phys. Commun. 10, 343-367 (global correlation
   coefficients).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "CORRELATION_LIMIT",
    "CONDITION_LIMIT",
    "jacobian_covariance",
    "correlation_matrix",
    "global_correlation",
    "identifiability_messages",
]

#: Global correlation coefficient (of one parameter with all others) above which the parameters
#: are reported as not separately identifiable. With k fixed at 0.25, the fits of synthetic
#: paper-003 materials reach 0.98 (t1, n); with k free 0.995-0.9999.
CORRELATION_LIMIT = 0.99
#: Condition number of the column-normalized Jacobian above which the fit is reported as
#: ill-conditioned (some combination of parameters is barely constrained).
CONDITION_LIMIT = 1e6


def jacobian_covariance(jacobian: np.ndarray):
    """Covariance of the parameters from the Jacobian of the weighted residuals, ``(J^T J)^-1``.

    Computed by SVD of the Jacobian with unit-norm columns (so the parameters' units do not affect
    the conditioning). Returns ``(covariance, condition_number)``; a singular Jacobian (a
    parameter, or a combination, without any effect on the model) gives an infinite covariance.
    """
    norms = np.linalg.norm(jacobian, axis=0)
    size = jacobian.shape[1]
    if np.any(norms == 0) or not np.all(np.isfinite(jacobian)):
        return np.full((size, size), np.inf), math.inf
    _, singular, vt = np.linalg.svd(jacobian / norms, full_matrices=False)
    # Singular values below rounding level of the largest carry no information about the parameters.
    if singular[-1] <= singular[0] * np.finfo(float).eps * max(jacobian.shape):
        return np.full((size, size), np.inf), math.inf
    scaled = (vt.T / singular**2) @ vt
    return scaled / np.outer(norms, norms), float(singular[0] / singular[-1])


def correlation_matrix(covariance: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", divide="ignore"):
        deviation = np.sqrt(np.diag(covariance))
        correlation = covariance / np.outer(deviation, deviation)
    return np.clip(correlation, -1.0, 1.0)  # rounding can reach 1 + eps


def global_correlation(covariance: np.ndarray) -> np.ndarray:
    """Global correlation coefficient of each parameter with all the others (as in MINUIT):
    ``sqrt(1 - 1 / (V_jj (V^-1)_jj))``; 1 means the parameter is a combination of the others."""
    with np.errstate(invalid="ignore", divide="ignore"):
        inverse = np.linalg.pinv(covariance)
        return np.sqrt(np.clip(1.0 - 1.0 / (np.diag(covariance) * np.diag(inverse)), 0.0, 1.0))


def identifiability_messages(model, free, values, covariance, condition_number, correlation_limit):
    """Messages about parameters the measurements do not determine (empty if all are fine).

    Three symptoms: a singular Jacobian; a parameter almost entirely predicted by the others
    (global correlation above ``correlation_limit``: paper 003's n, k and t1 with k free); a
    parameter whose 1-sigma error exceeds both its value and its typical (default) value (with k
    free the fit often runs to k ~ 0, where the Fresnel term no longer depends on k).
    """
    if math.isinf(condition_number) or not np.all(np.isfinite(covariance)):
        return [
            f"{model.name}: the free parameters {', '.join(free)} cannot all be determined from "
            "these measurements (singular Jacobian: some parameter or combination has no effect); "
            "fix some of them"
        ]
    problems = []
    if len(free) > 1:
        correlation = correlation_matrix(covariance)
        global_values = global_correlation(covariance)
        entangled = [
            f"{name} {rho:.4f}" for rho, name in sorted(zip(global_values, free), reverse=True)
            if rho > correlation_limit
        ]
        if entangled:
            a, b = np.unravel_index(np.argmax(np.abs(np.triu(correlation, 1))), correlation.shape)
            problems.append(
                f"global correlations {', '.join(entangled)} > {correlation_limit:g} (strongest "
                f"pair {free[a]}-{free[b]} {correlation[a, b]:+.4f}): these parameters trade off"
            )
    errors = np.sqrt(np.diag(covariance))
    undetermined = [
        f"{name} = {values[name]:.3g} ± {error:.3g}"
        for name, error in zip(free, errors)
        if error > abs(values[name]) and error > abs(model.parameter(name).default)
    ]
    if undetermined:
        problems.append(f"{', '.join(undetermined)} not determined (error larger than the value)")
    messages = []
    if problems:
        hint = " (paper 003 fixes k = 0.25)" if "k" in free else ""
        messages.append(
            f"{model.name}: parameters not identifiable from these measurements: "
            + "; ".join(problems) + f"; fix one of them{hint}"
        )
    elif condition_number > CONDITION_LIMIT:
        messages.append(
            f"{model.name}: ill-conditioned fit (condition number {condition_number:.3g} > "
            f"{CONDITION_LIMIT:g}); some combination of {', '.join(free)} is barely constrained"
        )
    return messages
