"""The solver behind the class fits from imagery: variable projection over the shape parameters.

The surface models are linear in their intensity terms (:attr:`Model.linear`) once the shape
parameters are fixed, ``f = sum_j p_j B_j(geometry; shape)``::

    torrance_sparrow(_simplified):  f = t0 + t1 * S(w, n, k)      S = F G exp(-w^2 a^2) / (cos ti cos tr)
    empirical:                      f = t0 + a  * E(b, c)         E = exp(b (ti tr)^2) exp(-c^2 (psi/2)^2)
    lambertian:                     f = t0
    kernel-driven (Ross-Li):        f = f_iso + f_vol K_vol + f_geo K_geo

so for a trial shape the intensities of *all* bands are solved at once by (non-negative) linear
least squares from the sums ``B^T B`` and ``B^T y`` (:class:`brdfcorr.fit.profile._LinearProfile`), and only the few
shape parameters (shared by the bands of a class) are searched: a coarse grid on a subsample, a
bounded Nelder-Mead refinement of the profile objective (variable projection), and Newton steps on
all samples. A model without free shape parameters (the kernel-driven models, Lambertian) is solved
in one pass: one design matrix, one linear solve, no search. Bands are weighted by the inverse
variance of their data so that bright near-infrared bands do not dominate the shape.

The pieces, from the bottom up: :mod:`brdfcorr.fit.shapes` (free and fixed shape parameters,
search ranges), :mod:`brdfcorr.fit.profile` (the linear profile), :mod:`brdfcorr.fit.shape_search`
(grid, Nelder-Mead, Newton), :mod:`brdfcorr.fit.class_errors` (the errors); this module puts them
together (:func:`fit_class_samples`).

Errors: one joint sandwich covariance over the free shape parameters and every band's intensities,
cluster-robust over spatial blocks with the small-sample corrections of issue 27 (CR2, effective
degrees of freedom; :func:`brdfcorr.fit.sandwich._joint_covariance`), the t-variance factor and the
``errors_reliable`` flag (:func:`brdfcorr.fit.class_errors._class_errors`; ``docs/uncertainty.md``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from brdfcorr.fit.class_errors import _class_errors
from brdfcorr.fit.profile import _LinearProfile, _profile
from brdfcorr.fit.shape_search import _at_edge, _coarse_shape, _newton_polish
from brdfcorr.fit.shapes import _resolve
from brdfcorr.fit.two_way import TwoWayClusters
from brdfcorr.fit.within import Levels
from brdfcorr.models import Model

__all__ = ["fit_class_samples", "Held", "GRID_POINTS", "LEVEL_TOLERANCE", "MAX_LEVEL_ITERATIONS", "SEARCH_SAMPLES",
           "UNCONSTRAINED_T"]


def _condition(design: np.ndarray) -> float:
    """Condition number of the design with unit-norm columns, from the eigenvalues of its Gram
    matrix (cond(A)^2 = cond(A^T A); accurate far beyond the guard rail's 1e3)."""
    gram = np.einsum("nk,nl->kl", design, design)
    norms = np.sqrt(np.diag(gram))
    norms = np.where(norms > 0, norms, 1.0)
    eigenvalues = np.linalg.eigvalsh(gram / np.outer(norms, norms))
    return float(np.sqrt(eigenvalues[-1] / eigenvalues[0])) if eigenvalues[0] > 0 else math.inf


#: With free levels, the fit is repeated with each group's views at the level of the previous fit at
#: its geometry (:mod:`brdfcorr.fit.within`) until those levels change by no more than this fraction
#: (in every band, of the band's largest level) from one fit to the next ...
LEVEL_TOLERANCE = 1e-7
#: ... or this many times (then the fit says that its levels did not converge: ``levels_converged``).
MAX_LEVEL_ITERATIONS = 30


#: Points per free shape parameter of the coarse search grid of a class fit (at most
#: :data:`brdfcorr.fit.shape_search.MAX_GRID_POINTS` in all).
GRID_POINTS = 9
#: Samples of the coarse shape search (a seeded subsample); the optimum is then polished and the
#: errors computed on all samples.
SEARCH_SAMPLES = 20_000


def fit_class_samples(model: str | Model, theta_i, theta_r, phi, brdf, *, fixed: Mapping[str, float] | None = None,
                      grid_points: int = GRID_POINTS, clusters=None, levels: Levels | None = None,
                      scenes=None) -> dict:
    """Fit one class: shape parameters shared by all bands, intensity terms per band. Without free
    shape parameters (kernel-driven models, Lambertian) the fit is one weighted linear least-squares
    solve: no search, no Newton steps.

    Parameters
    ----------
    model : str or Model
        A surface model of the registry with intensity terms (:func:`brdfcorr.fit.shapes.intensity_terms`).
    theta_i, theta_r, phi : array-like, shape (N,)
        Solar zenith, view zenith and relative azimuth of each sample [deg].
    brdf : array-like, shape (N, B)
        BRDF of each sample in each band [sr^-1] (reflectance factor / pi).
    fixed : mapping, optional
        Shape parameters held fixed (default: k = 0.25 for the Torrance-Sparrow models, as paper 003
        did). Intensity terms cannot be fixed.
    grid_points : int, default :data:`GRID_POINTS`
        Points per free shape parameter in the coarse search grid (on :data:`SEARCH_SAMPLES` of the
        samples at most).
    clusters : array-like of int, shape (N,), optional
        A cluster id per sample (e.g. its spatial block). Errors are then cluster-robust: samples of one
        cluster may share their errors (spatially correlated albedo, texture). Without clusters the
        samples are taken as independent (with ``levels``: the samples of a group are one cluster).
    levels : Levels, optional
        Groups of samples (pixels or patches seen several times; :mod:`brdfcorr.fit.within`) that each
        get a free level: the shape and the geometry-dependent intensities are fitted to the differences
        between the views of a group relative to its level, the constant term (t0, f_iso) is restored
        from the class's mean. Samples alone in their group, or in one without a positive mean, are left
        out. R^2, angular R^2, RMS and chi^2/dof are then those of the within-group differences.
        Clusters must hold whole groups.
    scenes : array-like of int, shape (N,), optional
        The scene (date, line) of each sample: the errors are then two-way cluster-robust, over
        ``clusters`` and over the scenes (:mod:`brdfcorr.fit.two_way`; one-way with one scene).

    Returns
    -------
    dict
        ``params`` and ``errors`` (dicts of per-band arrays; errors 0 for fixed parameters),
        ``covariance`` (B, p, p): the joint sandwich covariance of the free parameters ``free`` (shape
        and intensities, model signature order; CR2, with the t-variance factor of few spatial blocks:
        :func:`brdfcorr.fit.class_errors._class_errors`), ``n`` (samples), ``chi2_dof`` (per band: sum
        of squared residuals / (N - p) [sr^-2]), ``r2``, ``rmse`` (per band), ``condition`` (of the
        column-normalized linear design), ``shape`` (the free shape values), ``fixed`` (the fixed
        ones), ``at_edge`` (free shape parameters at an end of their search range,
        :func:`brdfcorr.fit.shapes.search_range`, that is not a closed physical bound), ``error_dof`` (B, p: effective
        degrees of freedom of each error), ``n_clusters`` (blocks, or samples without them),
        ``errors_reliable`` (bool) and ``errors_reason`` (why not; empty when reliable;
        :func:`brdfcorr.fit.identifiability.error_reliability`), ``n_groups`` (groups with free levels
        that hold two or more samples; None without ``levels``), ``if_held``: where shape
        parameters ended at the edge of their search range without the data constraining them
        (:func:`_hold_unconstrained`), the fit with them held at the middle of the range (a dict
        like this one, its ``held``: name -> :class:`Held`, those parameters in ``fixed``), else
        None; ``held`` ({} here). The caller chooses: fit-classes takes it for a class whose fit at
        the edge explains too little of its angular signal to be kept
        (:func:`brdfcorr.fit.classes._held_if_poor`); where the fit at the edge is good, its edge
        value is kept (holding it would change a fit the data support, if not significantly).
        ``level_iterations``: with free levels, the fits repeated until the groups' levels
        converged (:func:`_solve_with_levels`; None without free levels or where they did not
        converge within :data:`MAX_LEVEL_ITERATIONS`), and ``levels_converged`` (False only there).
    """
    model, fixed, free = _resolve(model, fixed)
    rows, clusters, levels = _repeated_only((theta_i, theta_r, phi, brdf, *(() if scenes is None else (scenes,))),
                                            clusters, levels)
    samples, spatial = rows[:4], clusters  # the edge test (_hold_unconstrained) pairs over the spatial clusters
    clusters = clusters if scenes is None else TwoWayClusters.of(clusters, rows[4])
    profile = _profile(model, *samples, fixed, levels=levels)
    if levels is not None and not profile.terms and not free:  # the level alone (Lambertian): nothing within
        levels, profile = None, _profile(model, *samples, fixed)
    coarse = _coarse_shape(model, fixed, free, samples, SEARCH_SAMPLES, grid_points, full=profile)[1] if free else {}
    shape = _newton_polish(profile, coarse) if free else {}
    profile, shape, solution, iterations = _solve_with_levels(profile, shape, samples, free)
    converged = {"level_iterations": iterations, "levels_converged": profile.levels is None or iterations is not None}
    held_profile, held_shape, held_solution, held = _hold_unconstrained(profile, shape, solution, spatial)
    if_held = None
    if held:
        if_held = {**_fit_summary(held_profile, held_shape, {**fixed, **{name: h.value for name, h in held.items()}},
                                  held_solution, clusters), "held": held, "if_held": None, **converged}
    return {**_fit_summary(profile, shape, fixed, solution, clusters), "held": {}, "if_held": if_held, **converged}


def _solve_with_levels(profile: _LinearProfile, shape: dict[str, float], samples: tuple,
                       free: list[str]) -> tuple[_LinearProfile, dict[str, float], _Solution, int | None]:
    """The linear solve at ``shape``; with free levels, then repeated with each group's views
    brought back to the model's level at its own geometry (:mod:`brdfcorr.fit.within`), the shape
    polished again each time, until those levels (N, B) [sr^-1] change by no more than
    :data:`LEVEL_TOLERANCE` of each band's largest, at most :data:`MAX_LEVEL_ITERATIONS` times.

    The repetition is a fixed-point iteration of the levels: at the truth the views relative to
    their group's mean, times the model's level there, are the model itself, so a noise-free class
    is recovered exactly once it has converged (linearly: about one digit per repetition).
    Returns the last profile, shape and solve, and the repetitions done (None without free levels
    or where they did not converge within the cap)."""
    solution = _Solution.of(profile, shape)
    levels = profile.levels
    if levels is None:
        return profile, shape, solution, None
    previous = np.broadcast_to(profile.scale, profile.raw_data.shape)  # the first fit's: the class's mean level
    for iteration in range(1, MAX_LEVEL_ITERATIONS + 1):
        group_model = np.maximum(levels.group_means(profile.raw_design(shape) @ solution.intensities), 1e-12)
        profile = _profile(profile.model, *samples, profile.fixed, levels=levels, group_model=group_model)
        shape = _newton_polish(profile, shape) if free else {}
        solution = _Solution.of(profile, shape)
        change = np.max(np.abs(group_model - previous), axis=0) / np.max(np.abs(group_model), axis=0)
        if np.all(change <= LEVEL_TOLERANCE):
            return profile, shape, solution, iteration
        previous = group_model
    return profile, shape, solution, None


#: A shape parameter that ends at the edge of its search range is held at the middle of the range
#: when the fit at the edge beats the fit with it held there by less than this many standard errors
#: over the clusters (:func:`_edge_advantage`): the data do not constrain it.
UNCONSTRAINED_T = 2.0


@dataclass(frozen=True)
class Held:
    """A free shape parameter held at the middle of its search range because the data do not
    constrain it (:func:`_hold_unconstrained`): the ``value`` held, the ``edge`` value the search
    ended at, and the fit's advantage there, ``t`` standard errors over ``clusters`` clusters."""

    value: float
    edge: float
    t: float
    clusters: int

    def note(self, name: str) -> str:
        """One line for the fit's notes."""
        return (f"{name} is not constrained by the data (the fit at the edge of its search range, {name} = "
                f"{self.edge:.4g}, is better than at {self.value:.4g} by {self.t:.2f} standard errors over "
                f"{self.clusters} clusters, < {UNCONSTRAINED_T:g}): held at {self.value:.4g}, the middle of the range")


def _middle(search: tuple[float, float, bool]) -> float:
    """The middle of a search range (geometric for a logarithmic one)."""
    low, high, logarithmic = search
    return math.sqrt(low * high) if logarithmic else 0.5 * (low + high)


def _edge_advantage(profile: _LinearProfile, edge: _Solution, held: _Solution, clusters) -> tuple[float, int]:
    """How much better the fit ``edge`` explains the data than ``held``, in standard errors over the
    clusters: the mean over clusters of the decrease of the weighted squared residuals (each band
    weighted as in the objective) divided by its standard error (a paired t statistic, robust to
    residuals shared within a cluster and across bands), and the number of clusters (samples
    without ``clusters``). 0 when the edge is no better at all."""
    gain = (profile.residuals(held.design, held.coefficients) ** 2
            - profile.residuals(edge.design, edge.coefficients) ** 2) @ profile.weights  # (N,)
    index = np.arange(gain.size) if clusters is None else np.unique(clusters, return_inverse=True)[1].reshape(-1)
    per_cluster = np.bincount(index, gain)
    count = per_cluster.size
    spread = per_cluster.std(ddof=1) if count > 1 else 0.0
    if per_cluster.sum() <= 0.0:
        return 0.0, count
    return (float(per_cluster.mean() / (spread / math.sqrt(count))) if spread > 0 else math.inf), count


def _hold_unconstrained(profile: _LinearProfile, shape: dict[str, float], solution: _Solution,
                        clusters) -> tuple[_LinearProfile, dict[str, float], _Solution, dict[str, Held]]:
    """Each shape parameter that ended at the edge of its search range (:func:`_at_edge`) and that
    the data do not constrain, held at the middle of its range, the others polished again.

    The edge is either where the data put the optimum (beyond the range) or where a flat profile
    drifted (the data cannot tell the values apart: n of a Torrance-Sparrow lobe seen over a few
    tens of degrees trades with t1). The fit held at the middle tells them apart: where the fit at
    the edge is better by less than :data:`UNCONSTRAINED_T` standard errors over the clusters
    (:func:`_edge_advantage`), the parameter is held there (and no longer at the edge); otherwise
    it stays at the edge (for the guard rails to judge). Returns the profile, shape, solve and the
    parameters held (:class:`Held`).
    """
    held: dict[str, Held] = {}
    for name in _at_edge(profile, shape):
        if name not in _at_edge(profile, shape):  # moved off its edge when another was held
            continue
        value = _middle(profile.ranges[name])
        trial_profile = profile.holding(name, value)
        rest = {key: shape_value for key, shape_value in shape.items() if key != name}
        trial_shape = _newton_polish(trial_profile, rest) if rest else {}
        trial = _Solution.of(trial_profile, trial_shape)
        t, count = _edge_advantage(profile, solution, trial, clusters)
        if t < UNCONSTRAINED_T:
            held[name] = Held(value, shape[name], t, count)
            profile, shape, solution = trial_profile, trial_shape, trial
    return profile, shape, solution, held


def _repeated_only(samples: tuple, clusters, levels: Levels | None) -> tuple[tuple, np.ndarray | None, Levels | None]:
    """The samples (theta_i, theta_r, phi [deg], brdf [sr^-1]), their clusters (flattened) and
    levels, with free ``levels`` reduced to the samples of groups that can be fitted within
    (:meth:`brdfcorr.fit.within.Levels.usable`; the groups stand for the clusters without them)."""
    clusters = None if clusters is None else np.asarray(clusters).reshape(-1)
    if levels is None:
        return samples, clusters, None
    brdf = samples[3]
    repeated = levels.usable(np.asarray(brdf, dtype=float).reshape(len(levels.factors[0]), -1))
    samples = tuple(np.asarray(values)[repeated] for values in samples)
    clusters = levels.factors[0][repeated] if clusters is None else clusters[repeated]
    return samples, clusters, levels.subset(repeated)


@dataclass(frozen=True)
class _Solution:
    """The linear solve at one shape: the design (N, m), the coefficients of its columns (m, B),
    the sums of squared residuals (B,) and every intensity term's values (with a restored
    constant; (len(model.linear), B) [sr^-1])."""

    design: np.ndarray
    coefficients: np.ndarray
    ssr: np.ndarray
    intensities: np.ndarray

    @classmethod
    def of(cls, profile: _LinearProfile, shape: dict[str, float]) -> _Solution:
        design = profile.design(shape)
        coefficients, ssr = profile.solve(design)
        return cls(design, coefficients, ssr, profile.full_intensities(shape, coefficients))


def _fit_summary(profile: _LinearProfile, shape: dict[str, float], fixed: dict[str, float], solution: _Solution,
                 clusters) -> dict:
    """The result dict of :func:`fit_class_samples` from its last profile, shape and solve."""
    model, design = profile.model, solution.design
    names, covariance, deviations, diagnostics = _class_errors(profile, shape, design, solution.coefficients,
                                                               solution.intensities, clusters)
    n_bands = profile.data.shape[1]
    params = {name: np.full(n_bands, value) for name, value in {**fixed, **shape}.items()}
    params.update(dict(zip(model.linear, solution.intensities)))
    errors = {name: np.zeros(n_bands) for name in fixed}
    errors.update({name: deviations[:, column] for column, name in enumerate(names)})
    return {
        "params": {name: params[name] for name in model.parameter_names},
        "errors": {name: errors[name] for name in model.parameter_names},
        "covariance": covariance,
        "free": names,
        "n": profile.n,
        "n_groups": None if profile.levels is None else profile.levels.n_groups,
        **_quality(profile, design, solution.coefficients, solution.ssr, len(names) + _absorbed(profile.levels)),
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
