"""Fit per-class, per-band BRDF model parameters from the imagery itself.

Every class (roof tile, concrete, grass, ...) is seen under many sun/view geometries across a wide
field-of-view line, overlapping lines or revisits. This module pools each class's valid pixels,
samples them reproducibly, and fits a registered surface model to them, one parameter set per class
with intensity terms per band.

The models are linear in their intensity terms once the shape parameters are fixed::

    torrance_sparrow(_simplified):  f = t0 + t1 * S(w, n, k)      S = F G exp(-w^2 a^2) / (cos ti cos tr)
    empirical:                      f = t0 + a  * E(b, c)         E = exp(b (ti tr)^2) exp(-c^2 (psi/2)^2)
    lambertian:                     f = t0

so for a trial shape the intensities of *all* bands are solved at once by (non-negative) linear
least squares from a handful of sums, and only the few shape parameters (shared by the bands of a
class) are searched: a coarse grid, then a bounded Nelder-Mead refinement of the profile objective
(variable projection). Bands are weighted by the inverse variance of their data so that bright
near-infrared bands do not dominate the shape.

Imagery holds reflectance factors R (0-1, "BRF"/"HDRF"); brdfcorr's models are BRDFs in sr^-1.
The fit uses f = R / pi (a Lambertian surface of reflectance R has BRDF R / pi), so the intensity
parameters in the resulting table are in sr^-1 like the goniometer fits of paper 003.

Errors: shape-parameter covariance from the sandwich estimator of the profile objective with
efficient per-sample scores summed over spatial blocks (cluster-robust: it allows for
heteroscedastic noise, for residuals correlated across bands such as within-class albedo
variation, and for albedo or texture correlated between neighbouring pixels within a block);
intensity errors per band from the cluster-robust covariance of the linear problem, plus the
propagated shape uncertainty. With strongly textured synthetic scenes the errors are still
optimistic by a factor of ~2-3 (measured over seeds with a 10 % albedo smoothed over ~4 pixels); a spatial block
bootstrap would be the next step.
"""

from __future__ import annotations

import itertools
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.sparse
import xarray as xr

from brdfcorr.errors import ParameterError
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import SURFACE_MODELS, Model, get_model

__all__ = [
    "ClassFitResult",
    "ClassSamples",
    "fit_classes",
    "sample_classes",
    "fit_one_class",
    "GuardRails",
    "ClassFit",
    "ClassFitWarning",
    "intensity_terms",
    "fit_class_samples",
]

def intensity_terms(model: Model) -> tuple[str, ...]:
    """The intensity terms of a model (its linear parameters, :attr:`Model.linear`): ``("t0", "t1")``
    for Torrance-Sparrow, ``("a", "t0")`` for the empirical model, ``("t0",)`` for Lambertian,
    ``("f_iso", "f_vol", "f_geo")`` for the kernel-driven models."""
    return model.linear


#: Shape parameters held fixed unless the caller frees them (paper 003 fixes k = 0.25: n, k and t1
#: cannot be retrieved together from reflectance alone).
DEFAULT_FIXED: dict[str, dict[str, float]] = {
    "torrance_sparrow": {"k": 0.25},
    "torrance_sparrow_simplified": {"k": 0.25},
}

#: Search ranges of the shape parameters (a subset of the physical bounds where BRDFs of natural
#: and man-made surfaces lie; Table 1 of paper 003 spans w = 0.032-0.153 deg^-1, n = 1.48-1.77),
#: and whether the grid is logarithmic.
SEARCH_RANGES: dict[str, tuple[float, float, bool]] = {
    "w": (0.005, 0.5, True),
    "n": (1.05, 4.0, False),
    "k": (0.0, 3.0, False),
    "b": (-3.0, 6.0, False),
    "c": (0.005, 0.5, True),
}


class ClassFitWarning(UserWarning):
    """A class failed a guard rail and fell back to a built-in material or to no correction."""


@dataclass(frozen=True)
class GuardRails:
    """Minimum requirements for a class fit to be used.

    Attributes
    ----------
    min_samples : int
        Minimum number of valid pixels of the class.
    min_vza_spread : float
        Minimum spread of the view zenith [deg] between its 5th and 95th percentiles.
    max_condition : float
        Maximum condition number of the column-normalized linear design ([1, basis]); above it the
        constant and the specular term cannot be told apart.
    min_r2 : float
        Minimum median (over bands) coefficient of determination.
    """

    min_samples: int = 500
    min_vza_spread: float = 10.0
    max_condition: float = 1e3
    min_r2: float = 0.0


@dataclass
class ClassFit:
    """The fit of one class, with its diagnostics.

    Attributes
    ----------
    class_id, name : int, str
        Class id and name.
    model : str
        Registered model name.
    n_samples : int
        Number of pixels fitted.
    vza_spread, phi_spread : float
        5th-95th percentile range of view zenith and relative azimuth among the samples [deg].
    condition : float
        Condition number of the column-normalized linear design at the fitted shape.
    params : dict of str to ndarray
        Every model parameter, one value per band (shape parameters repeated).
    errors : dict of str to ndarray
        1-sigma errors of the free parameters, per band (0 for fixed ones).
    r2, rmse : ndarray
        Per band: coefficient of determination, and residual RMS of the BRDF [sr^-1].
    fixed : dict
        The shape parameters held fixed.
    status : str
        ``"fitted"``, ``"fallback"`` (a built-in material replaces the fit) or ``"uncorrected"``.
    reasons : list of str
        Why the class failed its guard rails (empty when fitted).
    fallback : str or None
        The built-in material used instead, if any.
    """

    class_id: int
    name: str
    model: str
    n_samples: int
    vza_spread: float
    phi_spread: float
    condition: float = math.nan
    params: dict[str, np.ndarray] = field(default_factory=dict)
    errors: dict[str, np.ndarray] = field(default_factory=dict)
    r2: np.ndarray = field(default_factory=lambda: np.array([]))
    rmse: np.ndarray = field(default_factory=lambda: np.array([]))
    fixed: dict[str, float] = field(default_factory=dict)
    status: str = "fitted"
    reasons: list[str] = field(default_factory=list)
    fallback: str | None = None

    def summary(self) -> dict[str, object]:
        """JSON-friendly summary (medians over bands for per-band quantities)."""
        median = lambda values: float(np.median(values)) if np.size(values) else None  # noqa: E731
        return {
            "class_id": self.class_id,
            "name": self.name,
            "model": self.model,
            "status": self.status,
            "reasons": list(self.reasons),
            "fallback": self.fallback,
            "n_samples": self.n_samples,
            "vza_spread_deg": round(self.vza_spread, 3),
            "phi_spread_deg": round(self.phi_spread, 3),
            "condition": None if math.isnan(self.condition) else float(self.condition),
            "median_r2": median(self.r2),
            "median_rmse": median(self.rmse),
            "params": {k: _compact(v) for k, v in self.params.items()},
            "errors": {k: _compact(v) for k, v in self.errors.items()},
        }


def _compact(values: np.ndarray):
    """A scalar when all bands share the value, else a list."""
    values = np.asarray(values, dtype=float)
    if values.size and np.all(values == values.flat[0]):
        return float(values.flat[0])
    return values.tolist()


class _LinearProfile:
    """Sums of the data that the per-band linear solve needs, computed once per class."""

    def __init__(self, model: Model, geometry: ScatteringGeometry, data: np.ndarray, fixed: dict):
        self.model = model
        self.geometry = geometry
        self.data = data  # (N, B) BRDF [sr^-1]
        self.fixed = fixed
        self.terms = intensity_terms(model)
        lower = [model.parameter(name).lower for name in self.terms]
        if any(bound not in (0.0, -math.inf) for bound in lower):
            raise ParameterError(f"{model.name}: linear parameters need a lower bound of 0 or none")
        self.nonnegative = np.array([bound == 0.0 for bound in lower])
        self.n = data.shape[0]
        self.sum_y = data.sum(axis=0)
        self.sum_yy = np.einsum("nb,nb->b", data, data)
        variance = self.sum_yy / self.n - (self.sum_y / self.n) ** 2
        # Inverse-variance band weights; a constant band carries no shape information.
        self.weights = np.where(variance > 0, 1.0 / np.where(variance > 0, variance, 1.0), 0.0)

    def design(self, shape: Mapping[str, float]) -> np.ndarray:
        """The (N, m) design matrix: one column per linear term, at a trial shape."""
        terms = self.model.terms(self.geometry, {**self.fixed, **shape})
        return np.column_stack([np.broadcast_to(np.asarray(t, dtype=float), (self.n,)) for t in terms])

    def solve(self, design: np.ndarray):
        """Per-band linear coefficients (m, B) and sums of squared residuals (B,).

        Least squares with the terms whose lower bound is 0 kept >= 0, exactly: every face of the
        constraint box (which terms are free) is solved from the normal equations and the best
        feasible one kept per band (at most 2^m small solves for m <= 3 terms, all bands at once).
        Terms the geometry cannot tell apart (a near-singular face) are left at 0.
        """
        gram = design.T @ design  # (m, m)
        cross = design.T @ self.data  # (m, B)
        m, n_bands = cross.shape
        best = np.zeros((m, n_bands))
        best_ssr = self.sum_yy.copy()  # every coefficient 0
        for free in itertools.product((False, True), repeat=m):
            if not any(free):
                continue
            index = np.flatnonzero(free)
            sub = gram[np.ix_(index, index)]
            scale = np.sqrt(np.diag(sub))
            if not np.all(scale > 0) or np.linalg.cond(sub / np.outer(scale, scale)) > 1e12:
                continue
            values = np.linalg.solve(sub, cross[index])  # (k, B)
            feasible = np.all((values >= 0) | ~self.nonnegative[index, None], axis=0)
            ssr = self.sum_yy - np.einsum("kb,kb->b", values, cross[index])  # at the face optimum
            better = feasible & (ssr < best_ssr - 1e-12 * np.abs(best_ssr))
            if better.any():
                best[:, better] = 0.0
                best[np.ix_(index, better)] = values[:, better]
                best_ssr = np.where(better, ssr, best_ssr)
        return best, np.maximum(best_ssr, 0.0)

    def objective(self, shape: Mapping[str, float]) -> float:
        return float(self.solve(self.design(shape))[1] @ self.weights)


def _grid(name: str, points: int) -> np.ndarray:
    low, high, logarithmic = SEARCH_RANGES[name]
    return np.geomspace(low, high, points) if logarithmic else np.linspace(low, high, points)


def _grid_start(profile: _LinearProfile, free: Sequence[str], grid_points: int) -> dict[str, float]:
    """The best point of a coarse grid over the free shape parameters."""
    grids = np.meshgrid(*(_grid(name, grid_points) for name in free), indexing="ij")
    candidates = np.stack([g.ravel() for g in grids], axis=-1)
    values = [profile.objective(dict(zip(free, point))) for point in candidates]
    return dict(zip(free, candidates[int(np.nanargmin(values))]))


def _refine(profile: _LinearProfile, start: Mapping[str, float], step: float) -> dict[str, float]:
    """Bounded Nelder-Mead on the profile objective from ``start``; ``step`` sizes the simplex
    (relative for the logarithmic parameters w and c, in units of the search range otherwise)."""
    free = list(start)
    logarithmic = [SEARCH_RANGES[name][2] for name in free]
    # Optimize log(w), log(c) so that the simplex steps are relative.
    to_x = lambda p: np.array([math.log(v) if log else v for v, log in zip(p, logarithmic)])  # noqa: E731
    to_p = lambda x: np.array([math.exp(v) if log else v for v, log in zip(x, logarithmic)])  # noqa: E731
    low = to_x([SEARCH_RANGES[name][0] for name in free])
    high = to_x([SEARCH_RANGES[name][1] for name in free])
    x0 = np.clip(to_x([start[name] for name in free]), low, high)
    sizes = np.where(logarithmic, step, step * (high - low))
    simplex = np.vstack([x0, x0 + np.diag(np.where(x0 + sizes <= high, sizes, -sizes))])
    result = scipy.optimize.minimize(
        lambda x: profile.objective(dict(zip(free, to_p(x)))),
        x0,
        method="Nelder-Mead",
        bounds=list(zip(low, high)),
        # Stop when the simplex changes chi^2 by < 0.01 (the objective is ~ N B in chi^2 units).
        options={"xatol": 1e-4, "fatol": 0.01 * profile.objective(start) / profile.data.size,
                 "initial_simplex": simplex},
    )
    return dict(zip(free, map(float, to_p(result.x))))


def _derivatives(profile: _LinearProfile, shape: Mapping[str, float]):
    """Gradient and Hessian of the profile objective by central differences (steps 1e-3 relative)."""
    free = list(shape)
    values = np.array([shape[name] for name in free])
    steps = 1e-3 * np.maximum(np.abs(values), 1e-2)
    q = lambda vector: profile.objective(dict(zip(free, vector)))  # noqa: E731
    k = len(free)
    unit = np.eye(k) * steps
    q0 = q(values)
    plus = np.array([q(values + unit[i]) for i in range(k)])
    minus = np.array([q(values - unit[i]) for i in range(k)])
    gradient = (plus - minus) / (2 * steps)
    hessian = np.diag((plus - 2 * q0 + minus) / steps**2)
    for i in range(k):
        for j in range(i + 1, k):
            hessian[i, j] = hessian[j, i] = (
                q(values + unit[i] + unit[j]) - q(values + unit[i] - unit[j])
                - q(values - unit[i] + unit[j]) + q(values - unit[i] - unit[j])
            ) / (4 * steps[i] * steps[j])
    return values, steps, gradient, hessian


def _newton_polish(profile: _LinearProfile, shape: dict[str, float], iterations: int = 4):
    """Newton steps on the profile objective from a nearby start (few full-size evaluations).

    Returns the optimum and the Hessian there. Falls back to Nelder-Mead if the curvature is not
    positive definite (the start was not near a minimum).
    """
    free = list(shape)
    low = np.array([SEARCH_RANGES[name][0] for name in free])
    high = np.array([SEARCH_RANGES[name][1] for name in free])
    for _ in range(iterations):
        values, steps, gradient, hessian = _derivatives(profile, shape)
        if np.any(np.linalg.eigvalsh(hessian) <= 0):
            shape = _refine(profile, shape, 0.01)
            return shape, _derivatives(profile, shape)[3]
        change = -np.linalg.solve(hessian, gradient)
        shape = dict(zip(free, map(float, np.clip(values + change, low, high))))
        if np.all(np.abs(change) <= steps):  # moved less than the difference step: converged
            return shape, hessian
    return shape, _derivatives(profile, shape)[3]


def _cluster_sums(values: np.ndarray, clusters: np.ndarray | None) -> np.ndarray:
    """Per-cluster sums of per-sample rows (the identity without clusters)."""
    if clusters is None:
        return values
    _, index = np.unique(clusters, return_inverse=True)
    # A (clusters x samples) indicator matrix: one sparse product sums every column at once.
    indicator = scipy.sparse.csr_matrix(
        (np.ones(index.size), (index.reshape(-1), np.arange(index.size))), shape=(index.max() + 1, index.size)
    )
    return indicator @ values


def _errors(profile: _LinearProfile, shape: dict[str, float], intensities, ssr, hessian, clusters=None):
    """Sandwich covariance of the shape; robust sandwich + propagated shape errors for the
    intensities. With ``clusters`` the scores are summed per cluster first (cluster-robust
    covariance): samples of one cluster may share errors (e.g. spatially correlated albedo)."""
    free = list(shape)
    data, n = profile.data, profile.n
    design = profile.design(shape)
    coefficients = np.asarray(intensities)  # (m, B)
    residuals = data - design @ coefficients  # (N, B)

    # Intensities conditional on the shape: HC0 (or cluster-robust) sandwich per band.
    bread = np.linalg.pinv(design.T @ design)
    m = design.shape[1]
    meat = np.empty((residuals.shape[1], m, m))
    if clusters is None:
        squared = residuals**2
        for i in range(m):
            for j in range(i, m):
                meat[:, i, j] = meat[:, j, i] = (design[:, i] * design[:, j]) @ squared
    else:
        summed = [_cluster_sums(design[:, [i]] * residuals, clusters) for i in range(m)]  # (C, B)
        for i in range(m):
            for j in range(i, m):
                meat[:, i, j] = meat[:, j, i] = np.einsum("cb,cb->b", summed[i], summed[j])
    intensity_cov = np.einsum("ij,bjk,kl->bil", bread, meat, bread)
    intensity_var = np.stack([intensity_cov[:, i, i] for i in range(m)])
    if not free:
        return {}, np.sqrt(intensity_var)

    # The sandwich uses the estimator's own objective Q = sum_b w_b SSR_b (search weights w_b,
    # the inverse data variance) and its Hessian at the optimum.
    weights = profile.weights
    values = np.array([shape[name] for name in free])
    steps = 1e-3 * np.maximum(np.abs(values), 1e-2)
    k = len(free)

    # Per-pixel efficient scores of Q for the shape: the partial score minus its projection on the
    # intensity scores, g_theta - H_theta,c H_cc^-1 g_c, band by band (H_cc = 2 w_b A^T A).
    scores = np.empty((n, k))
    derivatives = []
    for i, name in enumerate(free):
        plus = profile.design({**shape, name: values[i] + steps[i]})
        minus = profile.design({**shape, name: values[i] - steps[i]})
        d_design = (plus - minus) / (2 * steps[i])  # (N, m); 0 in the constant columns
        partial = -2 * np.einsum("pm,mb,pb->p", d_design, coefficients, residuals * weights)
        # H_theta,c_b = 2 w_b h_b with h_b = A^T A' c_b - A'^T r_b; the projection
        # H_theta,c H_cc^-1 g_c,p summed over bands is -2 sum_b w_b r_pb a_p.(A^T A)^-1 h_b.
        h = design.T @ d_design @ coefficients - d_design.T @ residuals
        scores[:, i] = partial + 2 * np.einsum("pm,pb,mb->p", design, residuals * weights, bread @ h)
        derivatives.append((profile.solve(plus)[0] - profile.solve(minus)[0]) / (2 * steps[i]))
    inverse = np.linalg.pinv(hessian)
    scores = _cluster_sums(scores, clusters)
    shape_cov = inverse @ (scores.T @ scores) @ inverse
    shape_errors = dict(zip(free, np.sqrt(np.maximum(np.diag(shape_cov), 0.0))))

    # Propagate the shape uncertainty to the intensities: J cov J^T, J = d intensities / d shape.
    jacobian = np.stack(derivatives, axis=-1)  # (m, B, k)
    propagated = np.einsum("mbi,ij,mbj->mb", jacobian, shape_cov, jacobian)
    return shape_errors, np.sqrt(intensity_var + np.maximum(propagated, 0.0))


def fit_class_samples(
    model: str | Model,
    theta_i,
    theta_r,
    phi,
    brdf,
    *,
    fixed: Mapping[str, float] | None = None,
    grid_points: int = 9,
    search_samples: int = 20_000,
    clusters=None,
) -> dict:
    """Fit one class: shape parameters shared by all bands, intensity terms per band.

    Parameters
    ----------
    model : str or Model
        A surface model of the registry with intensity terms (:func:`intensity_terms`).
    theta_i, theta_r, phi : array-like, shape (N,)
        Solar zenith, view zenith and relative azimuth of each sample [deg].
    brdf : array-like, shape (N, B)
        BRDF of each sample in each band [sr^-1] (reflectance factor / pi).
    fixed : mapping, optional
        Shape parameters held fixed (default: k = 0.25 for the Torrance-Sparrow models, as paper
        003 did). Intensity terms cannot be fixed.
    grid_points : int, default 9
        Points per free shape parameter in the coarse search grid.
    search_samples : int, default 20000
        Samples used for the coarse search (a seeded subsample); the optimum is then polished and
        the errors computed on all samples.
    clusters : array-like of int, shape (N,), optional
        A cluster id per sample (e.g. its spatial block). Errors are then cluster-robust: samples
        of one cluster may share their errors (spatially correlated albedo, texture). Without
        clusters the samples are taken as independent.

    Returns
    -------
    dict
        ``params`` and ``errors`` (dicts of per-band arrays), ``r2``, ``rmse`` (per band),
        ``condition`` (of the column-normalized linear design), ``shape`` (the free shape values).
    """
    model = get_model(model)
    terms = intensity_terms(model)
    if not terms:
        fittable = [name for name in SURFACE_MODELS if get_model(name).linear]
        raise ParameterError(
            f"model {model.name!r} cannot be fitted to imagery; use one of {', '.join(fittable)}"
        )
    fixed = {**DEFAULT_FIXED.get(model.name, {}), **dict(fixed or {})}
    for name in fixed:
        if name in terms:
            raise ParameterError(f"{model.name}: the intensity term {name} cannot be fixed")
        model.parameter(name).check(fixed[name], model.name)
    free = [name for name in model.parameter_names if name not in terms and name not in fixed]

    data = np.asarray(brdf, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    geometry = ScatteringGeometry(*(np.asarray(a, dtype=float) for a in (theta_i, theta_r, phi)))
    profile = _LinearProfile(model, geometry, data, fixed)
    shape, hessian = {}, None
    if free:
        # Search on a subsample (the shape needs far fewer samples than the errors), then polish
        # on all samples from there: a large class costs a few full-size evaluations only.
        if data.shape[0] > search_samples:
            subset = np.random.default_rng(0).choice(data.shape[0], search_samples, replace=False)
            small = _LinearProfile(
                model,
                ScatteringGeometry(*(np.asarray(a, dtype=float)[subset] for a in (theta_i, theta_r, phi))),
                data[subset],
                fixed,
            )
            shape = _refine(small, _grid_start(small, free, grid_points), 0.1)
        else:
            shape = _refine(profile, _grid_start(profile, free, grid_points), 0.1)
        shape, hessian = _newton_polish(profile, shape)
    design = profile.design(shape)
    intensities, ssr = profile.solve(design)
    clusters = None if clusters is None else np.asarray(clusters).reshape(-1)
    shape_errors, intensity_errors = _errors(profile, shape, intensities, ssr, hessian, clusters)

    n_bands = data.shape[1]
    params = {name: np.full(n_bands, value) for name, value in {**fixed, **shape}.items()}
    params.update(dict(zip(terms, intensities)))
    errors = {name: np.full(n_bands, shape_errors.get(name, 0.0)) for name in (*fixed, *shape)}
    errors.update(dict(zip(terms, intensity_errors)))
    total = profile.sum_yy - profile.sum_y**2 / profile.n
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(total > 0, 1.0 - ssr / np.where(total > 0, total, 1.0), np.nan)
    norms = np.linalg.norm(design, axis=0)
    condition = float(np.linalg.cond(design / np.where(norms > 0, norms, 1.0)))
    return {
        "params": {name: params[name] for name in model.parameter_names},
        "errors": {name: errors[name] for name in model.parameter_names},
        "r2": r2,
        "rmse": np.sqrt(ssr / profile.n),
        "condition": condition,
        "shape": shape,
        "fixed": fixed,
    }


def _spread(values: np.ndarray) -> float:
    """5th-95th percentile range [deg]."""
    if values.size == 0:
        return 0.0
    low, high = np.percentile(values, [5, 95])
    return float(high - low)


def fit_one_class(
    class_id: int,
    name: str,
    model: str | Model,
    theta_i: np.ndarray,
    theta_r: np.ndarray,
    phi: np.ndarray,
    brdf: np.ndarray,
    *,
    fixed: Mapping[str, float] | None = None,
    guard: GuardRails = GuardRails(),
    fallback: str | None = None,
    grid_points: int = 9,
    clusters=None,
) -> ClassFit:
    """Fit one class's samples and apply the guard rails (see :func:`fit_class_samples`)."""
    model = get_model(model)
    report = ClassFit(
        class_id=class_id,
        name=name,
        model=model.name,
        n_samples=int(np.size(theta_i)),
        vza_spread=_spread(np.asarray(theta_r)),
        phi_spread=_spread(np.asarray(phi)),
        fallback=fallback,
    )
    if report.n_samples < guard.min_samples:
        report.reasons.append(f"{report.n_samples} samples < {guard.min_samples}")
    if report.vza_spread < guard.min_vza_spread:
        report.reasons.append(
            f"view zenith spread {report.vza_spread:.1f} deg < {guard.min_vza_spread:g} deg"
        )
    if report.n_samples >= max(len(model.parameters) + 1, 3):
        result = fit_class_samples(
            model, theta_i, theta_r, phi, brdf, fixed=fixed, grid_points=grid_points, clusters=clusters
        )
        report.params, report.errors = result["params"], result["errors"]
        report.r2, report.rmse = result["r2"], result["rmse"]
        report.condition, report.fixed = result["condition"], result["fixed"]
        if report.condition > guard.max_condition:
            report.reasons.append(
                f"ill-conditioned (condition {report.condition:.3g} > {guard.max_condition:g}): "
                "the geometry does not separate the diffuse and specular terms"
            )
        median_r2 = float(np.nanmedian(report.r2)) if np.size(report.r2) else math.nan
        # A Lambertian model explains no angular variation by construction (R^2 ~ 0): no guard.
        if len(model.linear) > 1 and not median_r2 >= guard.min_r2:
            report.reasons.append(f"median R^2 {median_r2:.3f} < {guard.min_r2:g}")
    if report.reasons:
        report.status = "fallback" if fallback else "uncorrected"
        action = f"using built-in material {fallback!r}" if fallback else "left uncorrected"
        warnings.warn(
            f"class {class_id} ({name}): {'; '.join(report.reasons)}; {action}",
            ClassFitWarning,
            stacklevel=2,
        )
    return report




@dataclass
class ClassSamples:
    """The pooled, sampled pixels of one class: angles [deg] and BRDF [sr^-1] per band."""

    theta_i: np.ndarray
    theta_r: np.ndarray
    phi: np.ndarray
    brdf: np.ndarray  # (N, B)
    block: np.ndarray | None = None  # spatial block id of each sample (cluster for the errors)


def _class_values(class_map: xr.DataArray) -> np.ndarray:
    """The class ids of a class map in memory, its nodata (rioxarray's) read as 0, "no class"."""
    values = np.asarray(class_map.values)
    nodata = class_map.rio.nodata if hasattr(class_map, "rio") else None
    return np.where(values == nodata, 0, values) if nodata is not None else values


def _as_list(value) -> list:
    return list(value) if isinstance(value, (list, tuple)) else [value]


def sample_classes(
    images,
    classes,
    angles,
    *,
    class_ids: Sequence[int] | None = None,
    max_samples: int = 50_000,
    seed: int = 0,
    reflectance_scale: float = 1.0,
    block_size: int = 32,
) -> dict[int, ClassSamples]:
    """Pool each class's valid pixels over one or many scenes and sample them reproducibly.

    Parameters
    ----------
    images : DataArray or list of DataArray, dims (band, y, x)
        Reflectance factors (numpy- or dask-backed); the band count must agree across scenes.
    classes : DataArray or list of DataArray, dims (y, x)
        Integer class maps on the images' grids; 0, negative values and the map's nodata
        (``.rio.nodata``) mean "no class".
    angles : Dataset or list of Dataset
        ``sza``, ``saa``, ``vza``, ``vaa`` [deg] on the images' grids (DESIGN.md conventions).
    class_ids : sequence of int, optional
        Classes to sample (default: every positive id found).
    max_samples : int, default 50000
        Cap per class, over all scenes together. Sampling without replacement, seeded.
    seed : int, default 0
        Seed of the sampler: the same inputs and seed give the same samples.
    reflectance_scale : float, default 1
        Multiplier that turns stored values into reflectance factors (e.g. 1e-4 for 0-10000).
    block_size : int, default 32
        Side [pixels] of the square spatial blocks whose ids label the samples
        (``ClassSamples.block``), so that the fit's errors allow for albedo and texture that are
        correlated between neighbouring pixels.

    Returns
    -------
    dict of int to ClassSamples
        BRDF = reflectance / pi [sr^-1]. Samples whose reflectance is not finite in some band are
        dropped after sampling, so a class may end up with fewer than ``max_samples``.

    Notes
    -----
    Only the class maps and the angle layers needed to find valid pixels are computed whole; the
    reflectance is read at the sampled pixels only (pointwise indexing stays lazy on dask).
    """
    images, classes, angles = _as_list(images), _as_list(classes), _as_list(angles)
    if not len(images) == len(classes) == len(angles):
        raise ParameterError(
            f"{len(images)} images, {len(classes)} class maps and {len(angles)} angle sets: "
            "give one class map and one angle set per image"
        )
    maps = [_class_values(class_map) for class_map in classes]
    valid_angles = [
        np.all([np.isfinite(np.asarray(a[name].values)) for name in ("sza", "saa", "vza", "vaa")], axis=0)
        for a in angles
    ]
    if class_ids is None:
        class_ids = sorted({int(c) for m in maps for c in np.unique(m) if c > 0})
    rng = np.random.default_rng(seed)
    pooled: dict[int, ClassSamples] = {}
    for class_id in class_ids:
        candidates = [np.flatnonzero((m == class_id) & ok) for m, ok in zip(maps, valid_angles)]
        counts = np.array([c.size for c in candidates])
        offsets = np.concatenate([[0], np.cumsum(counts)])
        chosen = np.sort(rng.choice(offsets[-1], size=min(max_samples, offsets[-1]), replace=False))
        scene_of = np.searchsorted(offsets, chosen, side="right") - 1
        parts = []
        for scene, (image, angle_set) in enumerate(zip(images, angles)):
            flat = candidates[scene][chosen[scene_of == scene] - offsets[scene]]
            if flat.size == 0:
                continue
            iy, ix = np.unravel_index(flat, maps[scene].shape)
            where = {"y": xr.DataArray(iy, dims="sample"), "x": xr.DataArray(ix, dims="sample")}

            def pick(array):
                # Pointwise (vectorized) indexing: lazy on dask, reads only the sampled pixels.
                return np.asarray(array.isel(where).values, dtype=float)

            reflectance = pick(image.transpose("band", "y", "x")).T * reflectance_scale
            saa, vaa = pick(angle_set["saa"]), pick(angle_set["vaa"])
            blocks_x = -(-maps[scene].shape[1] // block_size)
            block = (scene, iy // block_size, ix // block_size)
            parts.append(
                (pick(angle_set["sza"]), pick(angle_set["vza"]), relative_azimuth(saa, vaa), reflectance / math.pi,
                 (block[0] * 10**9 + block[1] * blocks_x + block[2]).astype(np.int64))
            )
        if not parts:
            n_bands = images[0].sizes["band"]
            pooled[class_id] = ClassSamples(
                *(np.empty(0) for _ in range(3)), np.empty((0, n_bands)), np.empty(0, np.int64)
            )
            continue
        theta_i, theta_r, phi, brdf, block = (np.concatenate(p) for p in zip(*parts))
        keep = np.all(np.isfinite(brdf), axis=1)
        pooled[class_id] = ClassSamples(theta_i[keep], theta_r[keep], phi[keep], brdf[keep], block[keep])
    return pooled


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
        A subsample (at most ``keep_samples`` per class) for plots.
    """

    table: object
    fits: list[ClassFit]
    samples: dict[int, ClassSamples]

    def report(self) -> list[dict[str, object]]:
        """JSON-friendly fit report, one entry per class."""
        return [fit.summary() for fit in self.fits]


def _entry(fit: ClassFit, wavelengths):
    from brdfcorr.models.materials import load_material
    from brdfcorr.params import ClassEntry

    if fit.status == "uncorrected":
        return None
    if fit.status == "fallback":
        material = load_material(fit.fallback)
        return ClassEntry(id=fit.class_id, name=fit.name, model=material.model.name, params=material.params)
    params = {name: _compact(values) for name, values in fit.params.items()}
    per_band = any(isinstance(value, list) for value in params.values())
    return ClassEntry(
        id=fit.class_id,
        name=fit.name,
        model=fit.model,
        params=params,
        wavelengths=[float(w) for w in wavelengths] if per_band and wavelengths is not None else None,
    )


def fit_classes(
    images,
    classes,
    angles,
    model: str | Model = "torrance_sparrow",
    *,
    class_models: Mapping[int, str] | None = None,
    names: Mapping[int, str] | None = None,
    class_ids: Sequence[int] | None = None,
    wavelengths: Sequence[float] | None = None,
    fixed: Mapping[str, float] | None = None,
    max_samples: int = 50_000,
    seed: int = 0,
    reflectance_scale: float = 1.0,
    block_size: int = 32,
    guard: GuardRails = GuardRails(),
    fallback: str | Mapping[int, str] | None = None,
    grid_points: int = 9,
    keep_samples: int = 2000,
    progress=None,
) -> ClassFitResult:
    """Fit a BRDF model per class (shape per class, intensities per band) from imagery.

    Parameters
    ----------
    images, classes, angles :
        One or many scenes; see :func:`sample_classes`.
    model : str or Model, default "torrance_sparrow"
        Surface model with intensity terms (:func:`intensity_terms`) for every class ...
    class_models : mapping of int to str, optional
        ... except these classes, which get their own model.
    names : mapping of int to str, optional
        Class names (default ``class_<id>``).
    class_ids : sequence of int, optional
        Classes to fit (default: every positive id in the class maps).
    wavelengths : sequence of float, optional
        Band centres [nm]; default: the images' ``wavelength`` coordinate if present. Written to
        the table so that it can be applied to other sensors by interpolation.
    fixed : mapping, optional
        Shape parameters held fixed (default k = 0.25 for the Torrance-Sparrow models).
    max_samples, seed, reflectance_scale, block_size :
        See :func:`sample_classes`. The errors are cluster-robust over the spatial blocks.
    guard : GuardRails
        Minimum samples, view-zenith spread, conditioning and R^2 a class must meet.
    fallback : str or mapping of int to str, optional
        Built-in material used for a class that fails its guard rails; without one the class is
        left out of the table (left uncorrected, and flagged by the correction). Either way a
        :class:`ClassFitWarning` says so.
    grid_points : int, default 9
        Coarse-grid points per free shape parameter.
    keep_samples : int, default 2000
        Samples per class kept in the result for plots.
    progress : callable, optional
        Called as ``progress(class_id)`` after each class (e.g. a progress bar's update).

    Returns
    -------
    ClassFitResult
    """
    from brdfcorr.params import ParameterTable

    scenes = _as_list(images)
    if wavelengths is None and "wavelength" in scenes[0].coords:
        wavelengths = np.asarray(scenes[0]["wavelength"].values, dtype=float).tolist()
    pooled = sample_classes(
        images, classes, angles, class_ids=class_ids, max_samples=max_samples, seed=seed,
        reflectance_scale=reflectance_scale, block_size=block_size,
    )
    names = dict(names or {})
    fits, entries, kept = [], [], {}
    for class_id, samples in pooled.items():
        class_model = (class_models or {}).get(class_id, model)
        class_fallback = fallback.get(class_id) if isinstance(fallback, Mapping) else fallback
        fit = fit_one_class(
            class_id,
            names.get(class_id, f"class_{class_id}"),
            class_model,
            samples.theta_i,
            samples.theta_r,
            samples.phi,
            samples.brdf,
            fixed=fixed,
            guard=guard,
            fallback=class_fallback,
            grid_points=grid_points,
            clusters=samples.block,
        )
        fits.append(fit)
        entry = _entry(fit, wavelengths)
        if entry is not None:
            entries.append(entry)
        step = max(1, samples.theta_i.size // keep_samples)
        kept[class_id] = ClassSamples(
            samples.theta_i[::step], samples.theta_r[::step], samples.phi[::step], samples.brdf[::step]
        )
        if progress is not None:
            progress(class_id)
    return ClassFitResult(table=ParameterTable(classes=entries), fits=fits, samples=kept)

