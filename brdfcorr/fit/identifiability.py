"""Whether goniometer measurements determine a model's parameters: covariance from the Jacobian
(heteroscedasticity-robust without measurement errors), correlations, and the identifiability
messages of :func:`brdfcorr.fit.goniometer.fit_brdf`.

Paper 003 (section 4) found that n, k and t1 of the Torrance-Sparrow model trade off unless k is
fixed; these diagnostics say so for any model and fit.

References
----------
.. [1] S. Brandt (1992): Datenanalyse. BI-Wissenschaftsverlag, p. 276 (errors of a non-linear
   least-squares fit from the linearized model, i.e. the inverse of J^T W J).
.. [2] F. James, M. Roos (1975): MINUIT. Comput. Phys. Commun. 10, 343-367 (global correlation
   coefficients).
.. [3] J. G. MacKinnon, H. White (1985): Some heteroskedasticity-consistent covariance matrix
   estimators with improved finite sample properties. J. Econometrics 29, 305-325 (HC3).
.. [4] R. M. Bell, D. F. McCaffrey (2002): Bias reduction in standard errors for linear regression with
   multi-stage samples. Survey Methodology 28, 169-181 (effective degrees of freedom of a
   cluster-robust variance).
"""

from __future__ import annotations

import math

import numpy as np

from brdfcorr.models.torrance_sparrow import K as TS_ABSORPTION

__all__ = [
    "other_minima",
    "CORRELATION_LIMIT",
    "CONDITION_LIMIT",
    "jacobian_covariance",
    "hc3_covariance",
    "robust_problem",
    "ROBUST_LEVERAGE_LIMIT",
    "correlation_matrix",
    "global_correlation",
    "identifiability_messages",
    "MIN_ERROR_DOF",
    "t_variance_factor",
    "error_reliability",
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


#: A measurement whose leverage is above this determines a parameter nearly alone: its residual is
#: ~0 whatever its noise, and the robust covariance cannot see that noise (:func:`robust_problem`).
ROBUST_LEVERAGE_LIMIT = 0.99


def leverages(jacobian: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """The leverage of each measurement, ``h_i = J_i (J^T J)^-1 J_i^T`` [-] (the hat matrix's diagonal)."""
    return np.einsum("ij,jk,ik->i", jacobian, covariance, jacobian)


def robust_problem(jacobian: np.ndarray, covariance: np.ndarray, dof: int) -> str | None:
    """Why the heteroscedasticity-robust covariance cannot be used (None where it can, or where the
    covariance is singular, which the identifiability warnings say): no degrees of freedom, or a
    measurement of leverage above :data:`ROBUST_LEVERAGE_LIMIT`."""
    if not np.all(np.isfinite(covariance)):
        return None
    if dof < 1:
        reason = "as many free parameters as measurements"
    elif np.max(leverages(jacobian, covariance)) > ROBUST_LEVERAGE_LIMIT:
        reason = "a measurement alone determines a parameter (leverage ~1)"
    else:
        return None
    return (f"{reason}: the errors without sigma are scaled by chi2/dof instead of robust ones, which "
            "assumes every measurement has the same noise; give the sigma column")


def hc3_covariance(jacobian: np.ndarray, residuals: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """The heteroscedasticity-robust (HC3, MacKinnon and White 1985) covariance of a least-squares
    fit without measurement errors: ``B (sum_i J_i^T J_i r_i^2 / (1 - h_i)^2) B`` with the bread
    ``B = (J^T J)^-1`` (``covariance``), residuals ``r`` and leverages ``h``. Valid where the noise
    differs between measurements (a goniometer's errors are relative: 4-15 % of a BRDF that spans
    two orders of magnitude), where ``(J^T J)^-1 chi2/dof`` is not. HC3 rather than HC2: the
    recommended form for samples under ~250 (Long and Ervin 2000, Am. Stat. 54, 217-224); on
    paper 003's roof tile and red aluminium with 4 % relative noise (120 measurements, k fixed) its
    errors are 0.98-1.18 of the Monte-Carlo spread, HC2's 0.73-0.94, the scaled ones' 0.21-0.66."""
    weights = residuals**2 / (1.0 - leverages(jacobian, covariance)) ** 2
    meat = jacobian.T @ (jacobian * weights[:, None])
    robust = covariance @ meat @ covariance
    return 0.5 * (robust + robust.T)


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


def identifiability_messages(model, free, values, covariance, condition_number, correlation_limit, others=()):
    """Messages about parameters the measurements do not determine (empty if all are fine).

    Four symptoms: a singular Jacobian; a parameter almost entirely predicted by the others
    (global correlation above ``correlation_limit``: paper 003's n, k and t1 with k free); a
    parameter whose 1-sigma error exceeds both its value and its typical (default) value (with k
    free the fit often runs to k ~ 0, where the Fresnel term no longer depends on k); another
    minimum (``others``: the free parameters of other starts' solutions that fit as well,
    :func:`other_minima`) more than :data:`MINIMA_SIGMA` errors away, which the errors, taken at
    one minimum, do not cover (a backscatter half alone: n < 1 and n > 1 fit alike).
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
    fitted = np.array([values[name] for name in free])
    for other in others:
        with np.errstate(divide="ignore", invalid="ignore"):
            distance = np.abs(np.asarray(other) - fitted) / errors
        if np.nanmax(distance, initial=0.0) > MINIMA_SIGMA:
            far = int(np.nanargmax(distance))
            problems.append(f"another minimum fits as well at {free[far]} = {other[far]:.4g}, {distance[far]:.0f} "
                            f"errors from {values[free[far]]:.4g}: the errors do not cover it")
            break
    messages = []
    if problems:
        # Paper 003's k is the Torrance-Sparrow absorption index; RPV's k (Minnaert) is another.
        hint = " (paper 003 fixes k = 0.25)" if "k" in free and model.parameter("k") is TS_ABSORPTION else ""
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


#: Errors [1 sigma] beyond which another minimum of a goniometer fit is named (:func:`identifiability_messages`).
MINIMA_SIGMA = 3.0


def other_minima(best, solutions, chi2_dof: float, weighted: bool = True) -> list[np.ndarray]:
    """The free parameters of the ``solutions`` (scipy ``least_squares`` results; cost = chi^2 / 2)
    other than ``best`` whose chi^2 lies within max(1, ``chi2_dof``) of its: as good a fit by
    the measurements' own scatter. Without sigmas (not ``weighted``) chi^2 is a sum of squares
    [sr^-2], and the reach one residual variance, ``chi2_dof`` (a reach of 1 sr^-2 took minima
    with 5.8 times the sum of squares for as good)."""
    reach = 0.5 * (max(1.0, chi2_dof) if weighted else chi2_dof)
    return [solution.x for solution in solutions
            if solution is not best and solution.cost - best.cost <= reach]


#: Effective degrees of freedom (:func:`brdfcorr.fit.sandwich._satterthwaite_dof`) below which the
#: errors of an imagery fit are flagged unreliable: the error of the error is then large (its
#: relative SD ~ 1/sqrt(2 nu) = 25 % at nu = 8) and the calibration of the t-variance factor rests on
#: an approximate nu. In the sweep of ``benchmarks/bench_small_scene_errors.py`` (both Torrance-Sparrow
#: models, the empirical model, Ross-Thick/Li-Sparse, RPV) the fits above it have pull SDs within
#: 0.85-1.15, or below (conservative: RPV's fits kept by the non-linearity rule under block-correlated
#: noise, 0.69-1.01; ``docs/uncertainty.md``).
MIN_ERROR_DOF = 8.0
#: An error larger than this fraction of a parameter's distance to the end of its range (physical
#: bound or search range) marks a strongly non-linear fit: the range ends within 2 errors.
NONLINEAR_FRACTION = 0.5
#: Leverage of one spatial block above which it alone determines a parameter combination.
MAX_BLOCK_LEVERAGE = 0.99


def t_variance_factor(dof):
    """The variance of a t distribution with ``dof`` degrees of freedom, ``nu / (nu - 2)`` [-]: an
    estimate divided by an error that is itself estimated with nu degrees of freedom has this
    variance, so errors multiplied by its square root give pulls of unit SD. Held at 2 (its value
    at nu = 4) below nu = 4, where the t variance grows without bound (such errors are flagged
    unreliable, :data:`MIN_ERROR_DOF`)."""
    dof = np.asarray(dof, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dof > 4.0, 1.0 + 2.0 / (dof - 2.0), 2.0)  # written so that nu = inf gives 1


def error_reliability(free, error_dof, n_clusters, max_leverage, at_edge=(), at_bound=(),
                      margins=None, scenes: bool = False) -> tuple[bool, str]:
    """Whether the errors of an imagery fit can be trusted, and why not (empty when they can).

    Parameters
    ----------
    free : sequence of str
        The free parameters, the columns of ``error_dof``.
    error_dof : array (B, p)
        Effective degrees of freedom of each parameter's variance per band [-].
    n_clusters : int
        Spatial blocks (samples without blocks) the errors were estimated from.
    max_leverage : float
        Largest leverage eigenvalue of one block [-].
    at_edge, at_bound : sequence of str
        Shape parameters at the edge of their search range; descriptions of intensities held at a
        bound (0) in some band. Their errors describe no sampling distribution (it is cut off).
    margins : (mapping of str to array (B,), array (B, p)), optional
        Each free parameter's distance to the nearest end of its range (physical bounds, search
        range) and the 1-sigma errors (columns in ``free`` order). An error above
        :data:`NONLINEAR_FRACTION` of that distance means the fit is strongly non-linear there:
        the estimate's distribution is skewed and cut off within two errors (issue 27: t1 and n
        of red concrete from few blocks reach errors of 60-90 % of t1, pull SDs 1.5-1.9).
    scenes : bool, default False
        ``n_clusters`` counts scenes (two-way errors over blocks and scenes, fewer scenes than
        blocks): more scenes, not smaller blocks, give the errors more degrees of freedom.

    Returns
    -------
    (bool, str)
        ``errors_reliable`` and the reasons it is False, joined by "; ".
    """
    reasons = []
    dof = np.min(np.atleast_2d(error_dof), axis=0)
    low = [f"{name} {value:.1f}" for name, value in zip(free, dof) if not value >= MIN_ERROR_DOF]
    if n_clusters < 2:
        reasons.append("all samples in one spatial block: no error can be estimated, none is given (smaller "
                       "blocks: fit-classes --block-size)")
    elif low:
        source, remedy = (("scenes (two-way over blocks and scenes)", "more scenes, or one-way errors over blocks")
                          if scenes else ("spatial blocks", "smaller blocks: fit-classes --block-size; or a larger "
                                                            "scene"))
        reasons.append(f"errors from {n_clusters} {source}: effective degrees of freedom {', '.join(low)} < "
                       f"{MIN_ERROR_DOF:g} ({remedy})")
    if max_leverage > MAX_BLOCK_LEVERAGE:
        reasons.append(f"one block alone determines a parameter combination (leverage {max_leverage:.3f})")
    if margins is not None:
        room, errors = margins
        for column, name in enumerate(free):
            spare = np.asarray(room[name], dtype=float)
            # A band where the parameter sits at the end of its range is told by at_edge / at_bound.
            ratio = np.max(np.where(spare > 0, np.asarray(errors)[:, column] / np.where(spare > 0, spare, 1.0), 0.0))
            if ratio > NONLINEAR_FRACTION:
                reasons.append(f"{name}: error {ratio:.2g} times its distance to the end of its range "
                               f"(> {NONLINEAR_FRACTION:g}: strongly non-linear)")
    reasons += [f"{name} at the edge of its search range" for name in at_edge]
    reasons += [f"{description} (at its bound)" for description in at_bound]
    return not reasons, "; ".join(reasons)
