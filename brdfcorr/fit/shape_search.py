"""The search for a class's shape parameters: the minimum of the profile objective
(:meth:`brdfcorr.fit.profile._LinearProfile.objective`) over the free shape parameters.

A coarse grid on a seeded subsample (:func:`_grid_start`, :func:`_search_subset`), a bounded
Nelder-Mead refinement (:func:`_refine`; variable projection) and Newton steps on all samples
(:func:`_newton_polish`); then which parameters ended at an end of their search range
(:func:`_at_edge`) and how far each lies from its bounds (:func:`_room`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import scipy.optimize

from brdfcorr.fit.profile import _LinearProfile, _profile
from brdfcorr.fit.shapes import EDGE_FRACTION
from brdfcorr.fit.within import Levels
from brdfcorr.models import Model

__all__ = ["MAX_GRID_POINTS"]


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


#: Newton steps of :func:`_newton_polish` at most. From a start near the minimum it converges in
#: two or three; a start at the end of a curved valley (the n-t1 valley of Torrance-Sparrow's lobe,
#: where a grid point at n = 1.05 can win) needs up to about ten.
NEWTON_ITERATIONS = 20

#: Halvings of a Newton step that does not lower the objective before the polish stops.
NEWTON_HALVINGS = 4


def _newton_polish(profile: _LinearProfile, shape: dict[str, float],
                   iterations: int = NEWTON_ITERATIONS) -> dict[str, float]:
    """Damped Newton steps on the profile objective from a nearby start (few full-size evaluations).

    Each step is the Newton step (clipped to the search ranges), halved up to
    :data:`NEWTON_HALVINGS` times until the objective does not rise; the polish stops when a step
    moves every parameter by less than its difference step (converged), when no halving lowers
    the objective (at the minimum within rounding), or after ``iterations`` steps. Falls back to
    Nelder-Mead if the curvature is not positive definite (the start was not near a minimum).
    Returns the optimum.
    """
    free = list(shape)
    low = np.array([profile.ranges[name][0] for name in free])
    high = np.array([profile.ranges[name][1] for name in free])
    value = profile.objective(shape)
    for _ in range(iterations):
        values, steps, gradient, hessian = _derivatives(profile, shape)
        if np.any(np.linalg.eigvalsh(hessian) <= 0):
            return _refine(profile, shape, 0.01)
        change = -np.linalg.solve(hessian, gradient)
        for _ in range(NEWTON_HALVINGS + 1):
            trial = np.clip(values + change, low, high)
            trial_value = profile.objective(dict(zip(free, trial)))
            if trial_value <= value:
                break
            change = 0.5 * change
        else:
            return shape  # no step along the Newton direction lowers the objective
        shape, value = dict(zip(free, map(float, trial))), trial_value
        if np.all(np.abs(trial - values) <= steps):  # moved less than the difference step: converged
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
