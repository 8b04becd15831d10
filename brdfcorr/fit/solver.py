"""The solver behind the class fits from imagery: variable projection over the shape parameters.

The surface models are linear in their intensity terms (:attr:`Model.linear`) once the shape
parameters are fixed, ``f = sum_j p_j B_j(geometry; shape)``::

    torrance_sparrow(_simplified):  f = t0 + t1 * S(w, n, k)      S = F G exp(-w^2 a^2) / (cos ti cos tr)
    empirical:                      f = t0 + a  * E(b, c)         E = exp(b (ti tr)^2) exp(-c^2 (psi/2)^2)
    lambertian:                     f = t0
    kernel-driven (Ross-Li):        f = f_iso + f_vol K_vol + f_geo K_geo

so for a trial shape the intensities of *all* bands are solved at once by (non-negative) linear
least squares from the sums ``B^T B`` and ``B^T y`` (:class:`_LinearProfile`), and only the few
shape parameters (shared by the bands of a class) are searched: a coarse grid on a subsample, a
bounded Nelder-Mead refinement of the profile objective (variable projection), and Newton steps on
all samples. A model without free shape parameters (the kernel-driven models, Lambertian) is solved
in one pass: one design matrix, one linear solve, no search. Bands are weighted by the inverse
variance of their data so that bright near-infrared bands do not dominate the shape.

Errors: one joint sandwich covariance over the free shape parameters and every band's intensities,
cluster-robust over spatial blocks with the small-sample corrections of issue 27 (CR2, effective
degrees of freedom; :func:`brdfcorr.fit.sandwich._joint_covariance`), the t-variance factor and the
``errors_reliable`` flag (:func:`_class_errors`; ``docs/uncertainty.md``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np
import scipy.optimize
import scipy.sparse

from brdfcorr.errors import ParameterError
from brdfcorr.fit.identifiability import error_reliability, t_variance_factor
from brdfcorr.fit.sandwich import _joint_covariance
from brdfcorr.fit.within import Levels, cluster_mean_variance, restored_constant, with_constant, with_level_variance
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import SURFACE_MODELS, Model, get_model

__all__ = [
    "DEFAULT_FIXED",
    "SEARCH_RANGES",
    "fit_class_samples",
    "MODEL_SEARCH_RANGES",
    "imagery_models",
    "intensity_terms",
    "search_range",
]

#: Shape parameters held fixed unless the caller frees them (paper 003 fixes k = 0.25: n, k and t1
#: cannot be retrieved together from reflectance alone).
DEFAULT_FIXED: dict[str, dict[str, float]] = {
    "torrance_sparrow": {"k": 0.25},
    "torrance_sparrow_simplified": {"k": 0.25},
    "ross_li_ts": {"k": 0.25},
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

#: Search ranges of the shape parameters of one model where they differ from :data:`SEARCH_RANGES`
#: (RPV's k is a Minnaert exponent, not Torrance-Sparrow's absorption index; |theta| = 1 is the
#: degenerate limit of the Henyey-Greenstein term).
MODEL_SEARCH_RANGES: dict[str, dict[str, tuple[float, float, bool]]] = {
    "rpv": {"k": (0.2, 2.0, False), "theta": (-0.9, 0.9, False), "rho_c": (0.0, 1.0, False)},
    "rpv_peak": {"k": (0.2, 2.0, False), "theta": (-0.9, 0.9, False), "rho_c": (0.0, 1.0, False)},
}

#: A shape parameter within this fraction of its search range (of log range for w, c) from either
#: end is "at the edge": the optimum probably lies outside, or the data do not constrain it. An end
#: that is a closed physical bound of the parameter (RPV's rho_c = 1: no hot spot) does not count.
EDGE_FRACTION = 1e-3


def intensity_terms(model: Model) -> tuple[str, ...]:
    """The intensity terms of a model (its linear parameters, :attr:`Model.linear`): ``("t0", "t1")``
    for Torrance-Sparrow, ``("a", "t0")`` for the empirical model, ``("t0",)`` for Lambertian,
    ``("f_iso", "f_vol", "f_geo")`` for the kernel-driven models."""
    return model.linear


def _free_shape(model: Model, fixed: Mapping[str, float]) -> list[str]:
    return [name for name in model.shape_names if name not in fixed]


def search_range(model: Model, name: str) -> tuple[float, float, bool] | None:
    """(low, high, logarithmic) search range of a shape parameter of a model, or None if it has
    none (:data:`MODEL_SEARCH_RANGES`, else :data:`SEARCH_RANGES`)."""
    return {**SEARCH_RANGES, **MODEL_SEARCH_RANGES.get(model.name, {})}.get(name)


def imagery_models() -> tuple[str, ...]:
    """Surface models that can be fitted to imagery: with intensity terms, and a search range for
    every shape parameter not held fixed by default."""
    fittable = []
    for name in SURFACE_MODELS:
        model = get_model(name)
        free = _free_shape(model, DEFAULT_FIXED.get(name, {}))
        if model.linear and all(search_range(model, shape) for shape in free):
            fittable.append(name)
    return tuple(fittable)


class _LinearProfile:
    """Sums of the data that the per-band linear solve needs, computed once per class.

    With ``levels`` (:class:`brdfcorr.fit.within.Levels`) every group has a free level: the data
    are taken relative to their group's mean, times the model's level at the group's geometry
    (``group_model``, (N, B) [sr^-1]; default the class's mean level ``scale`` everywhere), and
    like the design within groups (less their group means); the model's constant term
    (``constant``; t0, f_iso) drops out of the design (``terms`` are the others) and is restored
    by :meth:`full_intensities`.
    """

    def __init__(self, model: Model, geometry: ScatteringGeometry, data: np.ndarray, fixed: dict,
                 levels: Levels | None = None, group_model: np.ndarray | None = None):
        self.model = model
        self.geometry = geometry
        self.fixed = fixed
        self.levels = levels
        self.ranges = {name: search_range(model, name) for name in _free_shape(model, fixed)}
        lower = [model.parameter(name).lower for name in intensity_terms(model)]
        if any(bound not in (0.0, -math.inf) for bound in lower):
            raise ParameterError(f"{model.name}: linear parameters need a lower bound of 0 or none")
        self.raw_data, self.level, self.scale = data, None, None  # (N, B) BRDF [sr^-1]
        if levels is not None:  # relative to each group's level (N, B), and the class's mean level (B,)
            relative, self.level = levels.relative(data)
            self.scale = self.level.mean(axis=0)
            self.raw_data = relative * (self.scale if group_model is None else group_model)
        self.constant = self._constant_terms() if levels is not None else ()
        self.terms = tuple(name for name in intensity_terms(model) if name not in self.constant)
        # Columns of the raw design: those of ``terms``, and of the constant (with free levels).
        self.kept = [j for j, name in enumerate(intensity_terms(model)) if name in self.terms]
        self.constant_index = intensity_terms(model).index(self.constant[0]) if self.constant else None
        self.data = data if levels is None else levels.demean(self.raw_data)
        self.nonnegative = np.array([bound == 0.0 for name, bound in zip(intensity_terms(model), lower)
                                     if name in self.terms])
        self.n = data.shape[0]
        self.sum_y = self.data.sum(axis=0)
        self.sum_yy = np.einsum("nb,nb->b", self.data, self.data)
        variance = self.sum_yy / self.n - (self.sum_y / self.n) ** 2
        # Inverse-variance band weights; a constant band carries no shape information.
        self.weights = np.where(variance > 0, 1.0 / np.where(variance > 0, variance, 1.0), 0.0)

    def raw_design(self, shape: Mapping[str, float]) -> np.ndarray:
        """The (N, m) design matrix of every linear term of the model at a trial shape."""
        terms = self.model.terms(self.geometry, {**self.fixed, **shape})
        n = self.geometry.theta_i.size
        return np.column_stack([np.broadcast_to(np.asarray(t, dtype=float), (n,)) for t in terms])

    def design(self, shape: Mapping[str, float]) -> np.ndarray:
        """The (N, m) design matrix: one column per linear term of :attr:`terms`, at a trial
        shape (within groups where the levels are free)."""
        design = self.raw_design(shape)
        if self.levels is None:
            return design
        return self.levels.demean(design[:, self.kept])

    def _constant_terms(self) -> tuple[str, ...]:
        """The linear terms whose column is the same at every sample (the level: t0, f_iso), at
        the middle of the shape's search ranges."""
        middle = {name: (math.sqrt(low * high) if logarithmic else 0.5 * (low + high))
                  for name, (low, high, logarithmic) in self.ranges.items()}
        design = self.raw_design(middle)
        return tuple(name for name, column in zip(intensity_terms(self.model), design.T)
                     if np.ptp(column) == 0 and column[0] != 0)

    def full_intensities(self, shape: Mapping[str, float], coefficients: np.ndarray) -> np.ndarray:
        """Every linear term's intensities (model order; (m_all, B)) from those of :attr:`terms`
        (m, B): with free levels the constant term restored from the data's mean
        (:func:`brdfcorr.fit.within.restored_constant`; kept >= 0 if its lower bound is 0; one
        constant at most)."""
        if self.constant_index is None:
            return coefficients
        index, kept = self.constant_index, self.kept
        raw_means = self.raw_design(shape).mean(axis=0)
        constant = restored_constant(self.raw_data.mean(axis=0), raw_means[kept], coefficients, raw_means[index])
        if self.model.parameter(self.constant[0]).lower == 0.0:
            constant = np.maximum(constant, 0.0)
        full = np.empty((len(raw_means), coefficients.shape[1]))
        full[kept], full[index] = coefficients, constant
        return full

    def products(self, design: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``design.T @ design`` (m, m) and ``design.T @ data`` (m, B): the one pass over the data.

        By einsum, not BLAS: the tall-skinny products are memory-bound, so BLAS threads gain
        nothing, and on a loaded machine they stall at every one of their many barriers.
        """
        return np.einsum("nk,nl->kl", design, design), np.einsum("nk,nb->kb", design, self.data)

    def solve(self, design: np.ndarray):
        """Per-band linear coefficients (m, B) and sums of squared residuals (B,).

        Least squares with the terms whose lower bound is 0 kept >= 0 (those with lower bound -inf
        are free), exactly: every face of the constraint box (which terms are free) is solved from
        the normal equations and the best feasible one kept per band (at most 2^m - 1 small solves
        for m <= 3 terms, all bands at once). Terms the geometry cannot tell apart (a near-singular
        face) are left at 0. The data enter through one product ``design.T @ data``.
        """
        gram, cross = self.products(design)
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

    def angular_r2(self, design: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
        """How much of the *angular* signal the fit explains, per band (NaN where there is none).

        The samples are binned by geometry (:func:`geometry_bins`); the bin means average out
        albedo texture and noise, which are independent of the geometry, and leave the angular
        signal. This is R^2 of the bin means of the fit against those of the data, weighted by the
        bin counts: ~1 for a model that follows the angular signal however textured the class is,
        ~0 for one that explains none of it (plain R^2 is small for both on textured surfaces).
        The scatter the bin means keep (within-bin variance / count) is subtracted from both sums
        of squares, as in an adjusted R^2, so that few samples per bin do not read as misfit; NaN
        where no angular signal stands out of that scatter. The fit's bin means are those of the
        design columns times the coefficients (linear), so no (N, B) prediction is formed.
        """
        index = geometry_bins(self.geometry.theta_i, self.geometry.theta_r, self.geometry.phi)
        count = np.bincount(index).astype(float)
        keep = count >= MIN_BIN_COUNT
        if not keep.any():  # too few samples per geometry bin to tell the angular signal
            return np.full(self.data.shape[1], np.nan)
        indicator = scipy.sparse.csr_matrix(
            (np.ones(index.size), (index, np.arange(index.size))), shape=(count.size, index.size)
        )[keep]
        count = count[keep]
        observed = (indicator @ self.data) / count[:, None]  # (K, B)
        fitted = ((indicator @ design) / count[:, None]) @ coefficients  # (K, B)
        kept = keep[index]
        sum_yy = self.sum_yy if kept.all() else np.einsum("nb,nb->b", self.data[kept], self.data[kept])
        n_bins, n_kept = count.size, count.sum()
        scatter = np.maximum(sum_yy - count @ observed**2, 0.0) / max(n_kept - n_bins, 1.0)  # within-bin variance
        mean = count @ observed / n_kept
        total = count @ (observed - mean) ** 2 - (n_bins - 1) * scatter
        residual = np.maximum(count @ (observed - fitted) ** 2 - (n_bins - design.shape[1]) * scatter, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(total > 0, 1.0 - residual / np.where(total > 0, total, 1.0), np.nan)

    def r2(self, ssr: np.ndarray) -> np.ndarray:
        """Coefficient of determination per band (NaN for a constant band)."""
        total = self.sum_yy - self.sum_y**2 / self.n
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(total > 0, 1.0 - ssr / np.where(total > 0, total, 1.0), np.nan)


#: Geometry bins of :func:`geometry_bins` [deg] and the fewest samples a bin needs to count.
SUN_ZENITH_STEP, VIEW_ZENITH_STEP, MIN_BIN_COUNT = 5.0, 2.0, 10


def geometry_bins(theta_i, theta_r, phi) -> np.ndarray:
    """A bin number per sample: sun zenith in 5 deg steps, view zenith in 2 deg steps, and the
    half of the azimuth circle (backward phi < 90 deg or forward), the across-track geometry of a
    flight line."""
    sun = np.floor(np.asarray(theta_i) / SUN_ZENITH_STEP).astype(np.int64)
    view = np.floor(np.asarray(theta_r) / VIEW_ZENITH_STEP).astype(np.int64)
    forward = (np.asarray(phi) >= 90.0).astype(np.int64)
    _, index = np.unique(np.stack([sun, view, forward]), axis=1, return_inverse=True)
    return index.reshape(-1)


def _grid(search: tuple[float, float, bool], points: int) -> np.ndarray:
    low, high, logarithmic = search
    return np.geomspace(low, high, points) if logarithmic else np.linspace(low, high, points)


#: The coarse grid holds at most this many points: a model with more than three free shape
#: parameters (``rpv_peak``) gets fewer per parameter (3 each for five), so its search stays cheap.
MAX_GRID_POINTS = 9**3


def _grid_start(profile: _LinearProfile, free: Sequence[str], grid_points: int) -> dict[str, float]:
    """The best point of a coarse grid over the free shape parameters (at most
    :data:`MAX_GRID_POINTS` points in all)."""
    points = max(2, min(grid_points, int(MAX_GRID_POINTS ** (1.0 / len(free)) + 1e-9)))
    grids = np.meshgrid(*(_grid(profile.ranges[name], points) for name in free), indexing="ij")
    candidates = np.stack([g.ravel() for g in grids], axis=-1)
    values = [profile.objective(dict(zip(free, point))) for point in candidates]
    return dict(zip(free, candidates[int(np.nanargmin(values))]))


def _refine(profile: _LinearProfile, start: Mapping[str, float], step: float) -> dict[str, float]:
    """Bounded Nelder-Mead on the profile objective from ``start``; ``step`` sizes the simplex
    (relative for the logarithmic parameters w and c, in units of the search range otherwise)."""
    free = list(start)
    logarithmic = [profile.ranges[name][2] for name in free]
    # Optimize log(w), log(c) so that the simplex steps are relative.
    to_x = lambda p: np.array([math.log(v) if log else v for v, log in zip(p, logarithmic)])  # noqa: E731
    to_p = lambda x: np.array([math.exp(v) if log else v for v, log in zip(x, logarithmic)])  # noqa: E731
    low = to_x([profile.ranges[name][0] for name in free])
    high = to_x([profile.ranges[name][1] for name in free])
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


def _newton_polish(profile: _LinearProfile, shape: dict[str, float], iterations: int = 4) -> dict[str, float]:
    """Newton steps on the profile objective from a nearby start (few full-size evaluations).

    Returns the optimum. Falls back to Nelder-Mead if the curvature is not positive definite (the
    start was not near a minimum).
    """
    free = list(shape)
    low = np.array([profile.ranges[name][0] for name in free])
    high = np.array([profile.ranges[name][1] for name in free])
    for _ in range(iterations):
        values, steps, gradient, hessian = _derivatives(profile, shape)
        if np.any(np.linalg.eigvalsh(hessian) <= 0):
            return _refine(profile, shape, 0.01)
        change = -np.linalg.solve(hessian, gradient)
        shape = dict(zip(free, map(float, np.clip(values + change, low, high))))
        if np.all(np.abs(change) <= steps):  # moved less than the difference step: converged
            return shape
    return shape


def _search(profile: _LinearProfile, free: Sequence[str], grid_points: int) -> dict[str, float]:
    """Coarse grid, then Nelder-Mead: the shape that minimizes the profile objective."""
    return _refine(profile, _grid_start(profile, free, grid_points), 0.1)


def _at_edge(profile: _LinearProfile, shape: Mapping[str, float]) -> list[str]:
    """The shape parameters within :data:`EDGE_FRACTION` of an end of their search range that is
    not a closed physical bound."""
    edges = []
    for name, value in shape.items():
        low, high, logarithmic = profile.ranges[name]
        parameter = profile.model.parameter(name)
        if logarithmic:
            position = math.log(value / low) / math.log(high / low)
        else:
            position = (value - low) / (high - low)
        low_edge = position < EDGE_FRACTION and not (low == parameter.lower and not parameter.lower_open)
        high_edge = position > 1 - EDGE_FRACTION and high != parameter.upper
        if low_edge or high_edge:
            edges.append(name)
    return edges


def _room(profile: _LinearProfile, name: str, value: np.ndarray) -> np.ndarray:
    """Distance of a fitted parameter (per band) to the nearest end of the range it was fitted in:
    its physical bounds, narrowed for a shape parameter to its search range [its units]."""
    parameter = profile.model.parameter(name)
    low, high = parameter.lower, parameter.upper
    if name in profile.ranges:
        low, high = max(low, profile.ranges[name][0]), min(high, profile.ranges[name][1])
    return np.minimum(value - low, high - value)


def _at_bound(model: Model, intensities: np.ndarray) -> list[str]:
    """The intensity terms held at their lower bound 0 by the non-negative solve, with the bands
    (1-based) where they are: their errors describe no sampling distribution."""
    held = []
    for name, values, nonnegative in zip(model.linear, intensities, (model.parameter(t).lower == 0.0
                                                                      for t in model.linear)):
        bands = np.flatnonzero(np.asarray(values) == 0.0) if nonnegative else []
        if len(bands):
            held.append(f"{name} = 0 in band{'s' if len(bands) > 1 else ''} {', '.join(str(b + 1) for b in bands)}")
    return held


def _condition(design: np.ndarray) -> float:
    """Condition number of the design with unit-norm columns, from the eigenvalues of its Gram
    matrix (cond(A)^2 = cond(A^T A); accurate far beyond the guard rail's 1e3)."""
    gram = np.einsum("nk,nl->kl", design, design)
    norms = np.sqrt(np.diag(gram))
    norms = np.where(norms > 0, norms, 1.0)
    eigenvalues = np.linalg.eigvalsh(gram / np.outer(norms, norms))
    return float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else math.inf


def _check_model(model: Model, fixed: Mapping[str, float] | None) -> dict[str, float]:
    """The shape parameters held fixed (defaults and the caller's), validated."""
    terms = intensity_terms(model)
    if not terms:
        raise ParameterError(
            f"model {model.name!r} cannot be fitted to imagery; use one of {', '.join(imagery_models())}"
        )
    fixed = {**DEFAULT_FIXED.get(model.name, {}), **dict(fixed or {})}
    for name in fixed:
        if name in terms:
            raise ParameterError(f"{model.name}: the intensity term {name} cannot be fixed")
        model.parameter(name).check(fixed[name], model.name)
    missing = [name for name in _free_shape(model, fixed) if search_range(model, name) is None]
    if missing:
        raise ParameterError(
            f"{model.name}: no search range for the shape parameter(s) {', '.join(missing)}; fix them"
        )
    return fixed


#: With free levels, the fit is repeated this many times with each group's views at the level of
#: the previous fit at its geometry (:mod:`brdfcorr.fit.within`).
LEVEL_ITERATIONS = 3


def _profile(model, theta_i, theta_r, phi, brdf, fixed, subset=None, levels: Levels | None = None,
             group_model: np.ndarray | None = None) -> _LinearProfile:
    angles = [np.asarray(a, dtype=float).reshape(-1) for a in (theta_i, theta_r, phi)]
    data = np.asarray(brdf, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    if subset is not None:
        angles, data = [a[subset] for a in angles], data[subset]
        levels = None if levels is None else levels.subset(subset)
    return _LinearProfile(model, ScatteringGeometry(*angles), data, fixed, levels, group_model)


def _search_subset(n: int, search_samples: int, levels: Levels | None = None) -> np.ndarray | None:
    """A seeded subsample of about ``search_samples`` indices (None: use all ``n``); with free
    levels, whole groups of the main factor (a group's views are fitted together or not at all)."""
    if n <= search_samples:
        return None
    rng = np.random.default_rng(0)
    if levels is None:
        return rng.choice(n, search_samples, replace=False)
    groups = levels.n_groups
    chosen = rng.choice(groups, max(2, groups * search_samples // n), replace=False)
    return np.flatnonzero(np.isin(levels.factors[0], chosen))


def _resolve(model: str | Model, fixed: Mapping[str, float] | None) -> tuple[Model, dict[str, float], list[str]]:
    """The registry model, its fixed shape parameters (the defaults and the caller's, validated by
    :func:`_check_model`) and its free ones."""
    model = get_model(model)
    fixed = _check_model(model, fixed)
    return model, fixed, _free_shape(model, fixed)


def _coarse_shape(
    model: Model,
    fixed: dict[str, float],
    free: Sequence[str],
    samples: tuple,
    search_samples: int,
    grid_points: int,
    full: _LinearProfile | None = None,
) -> tuple[_LinearProfile, dict[str, float]]:
    """The shape of the coarse search (:func:`_search`: grid and Nelder-Mead; empty without free
    shape parameters) on a seeded subsample of at most ``search_samples`` of the ``samples``
    (theta_i, theta_r, phi [deg], brdf [sr^-1]), and the profile of that subsample.

    ``full``, the profile of all the samples if the caller has it, is searched itself when there
    are no more than ``search_samples``.
    """
    levels = None if full is None else full.levels
    subset = _search_subset(np.shape(samples[0])[0] if full is None else full.n, search_samples, levels)
    profile = full if subset is None and full is not None else _profile(model, *samples, fixed, subset, levels)
    return profile, (_search(profile, free, grid_points) if free else {})


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
    levels: Levels | None = None,
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
        clusters the samples are taken as independent (with ``levels``: the samples of a group
        are one cluster).
    levels : Levels, optional
        Groups of samples (pixels or patches seen several times; :mod:`brdfcorr.fit.within`)
        that each get a free level: the shape and the geometry-dependent intensities are fitted to
        the differences between the views of a group relative to its level, the constant term
        (t0, f_iso) is restored from the class's mean. Samples alone in their group, or in one
        without a positive mean, are left out. R^2, angular R^2, RMS
        and chi^2/dof are then those of the within-group differences. Clusters must hold whole
        groups.

    Returns
    -------
    dict
        ``params`` and ``errors`` (dicts of per-band arrays; errors 0 for fixed parameters),
        ``covariance`` (B, p, p): the joint sandwich covariance of the free parameters ``free``
        (shape and intensities, model signature order; CR2, with the t-variance factor of few
        spatial blocks: :func:`_class_errors`), ``n`` (samples),
        ``chi2_dof`` (per band: sum of squared residuals / (N - p) [sr^-2]), ``r2``, ``rmse`` (per band),
        ``condition`` (of the column-normalized linear design), ``shape`` (the free shape values),
        ``fixed`` (the fixed ones), ``at_edge`` (free shape parameters at an end of their
        search range, :func:`search_range`, that is not a closed physical bound), ``error_dof``
        (B, p: effective degrees of freedom of each error), ``n_clusters`` (blocks, or samples
        without them), ``errors_reliable`` (bool) and ``errors_reason`` (why not; empty when
        reliable; :func:`brdfcorr.fit.identifiability.error_reliability`), ``n_groups`` (groups
        with free levels that hold two or more samples; None without ``levels``).

    Notes
    -----
    Without free shape parameters (kernel-driven models, Lambertian) the fit is one weighted
    linear least-squares solve: no search, no Newton steps.
    """
    model, fixed, free = _resolve(model, fixed)
    samples = (theta_i, theta_r, phi, brdf)
    clusters = None if clusters is None else np.asarray(clusters).reshape(-1)
    if levels is not None:
        repeated = levels.usable(np.asarray(brdf, dtype=float).reshape(len(levels.factors[0]), -1))
        samples = tuple(np.asarray(values)[repeated] for values in samples)
        clusters = levels.factors[0][repeated] if clusters is None else clusters[repeated]
        levels = levels.subset(repeated)
    profile = _profile(model, *samples, fixed, levels=levels)
    if levels is not None and not profile.terms and not free:  # the level alone (Lambertian): nothing within
        levels, profile = None, _profile(model, *samples, fixed)
    shape: dict[str, float] = {}
    if free:
        # Search on a subsample (the shape needs far fewer samples than the errors), then polish
        # on all samples from there: a large class costs a few full-size evaluations only.
        _, coarse = _coarse_shape(model, fixed, free, samples, search_samples, grid_points, full=profile)
        shape = _newton_polish(profile, coarse)
    design = profile.design(shape)
    coefficients, ssr = profile.solve(design)
    intensities = profile.full_intensities(shape, coefficients)
    for _ in range(LEVEL_ITERATIONS if levels is not None else 0):
        # Each group's views back at the model's level at its own geometry (brdfcorr.fit.within).
        group_model = levels.group_means(profile.raw_design(shape) @ intensities)
        profile = _profile(model, *samples, fixed, levels=levels, group_model=np.maximum(group_model, 1e-12))
        shape = _newton_polish(profile, shape) if free else {}
        design = profile.design(shape)
        coefficients, ssr = profile.solve(design)
        intensities = profile.full_intensities(shape, coefficients)
    names, covariance, deviations, diagnostics = _class_errors(profile, shape, design, coefficients, intensities,
                                                               clusters)
    n_bands = profile.data.shape[1]
    params = {name: np.full(n_bands, value) for name, value in {**fixed, **shape}.items()}
    params.update(dict(zip(model.linear, intensities)))
    errors = {name: np.zeros(n_bands) for name in fixed}
    errors.update({name: deviations[:, column] for column, name in enumerate(names)})
    return {
        "params": {name: params[name] for name in model.parameter_names},
        "errors": {name: errors[name] for name in model.parameter_names},
        "covariance": covariance,
        "free": names,
        "n": profile.n,
        "n_groups": None if profile.levels is None else profile.levels.n_groups,
        **_quality(profile, design, coefficients, ssr, len(names) + _absorbed(profile.levels)),
        "condition": _condition(design),
        "shape": shape,
        "fixed": fixed,
        **diagnostics,
    }


def _quality(profile: _LinearProfile, design: np.ndarray, intensities: np.ndarray, ssr: np.ndarray,
             n_free: int) -> dict[str, np.ndarray]:
    """``chi2_dof``, ``r2``, ``angular_r2`` and ``rmse`` per band of the linear coefficients
    ``intensities`` (m, B) with the sums of squared residuals ``ssr`` (B,) and ``n_free`` free
    parameters (with free levels: of the views within groups, each at the model's level of its
    group)."""
    dof = profile.n - n_free
    return {
        "chi2_dof": ssr / dof if dof > 0 else np.full(ssr.shape, np.nan),
        "r2": profile.r2(ssr),
        "angular_r2": profile.angular_r2(design, intensities),
        "rmse": np.sqrt(ssr / profile.n),
    }


def _absorbed(levels: Levels | None) -> int:
    """Degrees of freedom taken by the free levels (one per group of each factor, less the mean
    of the second that the first holds already)."""
    return 0 if levels is None else sum(int(count.size) for count in levels.counts) - len(levels.counts)


def _with_levels(profile: _LinearProfile, shape: dict[str, float], coefficients, intensities, covariance, clusters):
    """The joint covariance of a fit with free levels (over the shape and
    :attr:`_LinearProfile.terms`) with the restored constant appended (:func:`_with_level`) and
    the uncertainty of the class's mean level, cluster-robust over ``clusters``
    (:func:`brdfcorr.fit.within.with_level_variance`)."""
    if profile.constant:
        covariance = _with_level(profile, shape, coefficients, covariance, clusters)
    joint = [*profile.kept, *([] if profile.constant_index is None else [profile.constant_index])]
    relative_variance = cluster_mean_variance(profile.level, clusters) / profile.scale**2
    return with_level_variance(covariance, intensities[joint].T, relative_variance)


def _with_level(profile: _LinearProfile, shape: dict[str, float], coefficients, covariance, clusters):
    """The joint covariance with the restored constant term appended (last;
    :func:`brdfcorr.fit.within.with_constant`): its Jacobian through the means of the raw design
    columns (central differences over the shape), and the variance of the mean relative level,
    cluster-robust over ``clusters`` (:func:`brdfcorr.fit.within.cluster_mean_variance`)."""
    kept, index = profile.kept, profile.constant_index
    raw = profile.raw_design(shape)
    means = raw.mean(axis=0)
    jacobian = []
    for name, value in shape.items():
        step = 1e-3 * max(abs(value), 1e-2)
        plus = profile.raw_design({**shape, name: value + step}).mean(axis=0)
        minus = profile.raw_design({**shape, name: value - step}).mean(axis=0)
        derivative = (plus - minus) / (2 * step)
        jacobian.append(-(derivative[kept] @ coefficients) / means[index])
    jacobian += [np.full(coefficients.shape[1], -means[j] / means[index]) for j in kept]
    levels = profile.raw_data - raw[:, kept] @ coefficients  # (N, B): each sample's level
    variance = cluster_mean_variance(levels, clusters)
    return with_constant(covariance, np.stack(jacobian, axis=1), variance / means[index] ** 2)


def _class_errors(profile: _LinearProfile, shape: dict[str, float], design, coefficients, intensities, clusters):
    """The free parameters (model signature order), their covariance (B, p, p) and 1-sigma errors
    (B, p), and the diagnostics: ``at_edge``, ``error_dof``, ``n_clusters``, ``errors_reliable``,
    ``errors_reason``. ``coefficients`` are the intensities of the profile's terms (the design's
    columns), ``intensities`` every linear term's (with a restored constant, :func:`_with_level`).

    The covariance is the CR2 sandwich (:func:`brdfcorr.fit.sandwich._joint_covariance`) with each
    parameter's variance multiplied by the t-variance factor of its effective degrees of freedom
    (:func:`brdfcorr.fit.identifiability.t_variance_factor`; correlations unchanged), so that the
    pulls ``(fit - truth) / error`` have unit SD with few spatial blocks too; whether they can be
    trusted is :func:`brdfcorr.fit.identifiability.error_reliability` (``docs/uncertainty.md``).
    """
    model = profile.model
    sandwich = _joint_covariance(profile, shape, design, coefficients, clusters)
    joint_names = [*shape, *profile.terms]
    joint, dof = sandwich.covariance, sandwich.dof
    if profile.levels is not None:
        joint = _with_levels(profile, shape, coefficients, intensities, joint, clusters)
    if profile.constant:
        dof = np.column_stack([dof, np.full(dof.shape[0], max(sandwich.n_clusters - 1, 1.0))])
        joint_names += list(profile.constant)
    names = tuple(name for name in model.parameter_names if name in joint_names)
    order = [joint_names.index(name) for name in names]
    error_dof = dof[:, order]
    inflation = np.sqrt(t_variance_factor(error_dof))  # (B, p)
    covariance = joint[:, order][:, :, order] * inflation[:, :, None] * inflation[:, None, :]
    deviations = np.sqrt(np.maximum(np.diagonal(covariance, axis1=1, axis2=2), 0.0))  # (B, p)
    at_edge = _at_edge(profile, shape)
    values = {**shape, **dict(zip(model.linear, intensities))}
    room = {name: _room(profile, name, np.asarray(values[name], dtype=float)) for name in names}
    reliable, reason = error_reliability(names, error_dof, sandwich.n_clusters, sandwich.max_leverage,
                                         at_edge, _at_bound(model, intensities), (room, deviations))
    return names, covariance, deviations, {"at_edge": at_edge, "error_dof": error_dof,
                                           "n_clusters": sandwich.n_clusters, "errors_reliable": reliable,
                                           "errors_reason": reason}
