"""How well a surface model explains a class's samples: R^2, angular R^2, RMS and chi^2/dof of
given weights (:func:`fit_quality`, e.g. a shape prior's posterior, :mod:`brdfcorr.fit.prior`),
and the median R^2 of a model's best fit found cheaply (:func:`median_r2`, the model suggestion of
:func:`brdfcorr.fit.classes.fit_one_class`). Both use the sums of the solver's linear profile
(:mod:`brdfcorr.fit.solver`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from brdfcorr.fit.solver import _coarse_shape, _profile, _quality, _resolve
from brdfcorr.models import Model

__all__ = ["fit_quality", "median_r2"]


def fit_quality(model: str | Model, theta_i, theta_r, phi, brdf, intensities, *,
                shape: Mapping[str, float] | None = None,
                fixed: Mapping[str, float] | None = None) -> dict[str, np.ndarray]:
    """How well given intensities explain the samples: what
    :func:`brdfcorr.fit.solver.fit_class_samples` reports of its own solution (``chi2_dof``,
    ``r2``, ``angular_r2``, ``rmse`` per band), for any other, e.g. the posterior of a shape prior
    (:mod:`brdfcorr.fit.prior`).

    Parameters
    ----------
    model, theta_i, theta_r, phi, brdf
        The model and the samples, as for :func:`brdfcorr.fit.solver.fit_class_samples`.
    intensities : array-like, shape (m, B)
        The model's linear terms (:attr:`Model.linear` order) per band [sr^-1].
    shape : mapping, optional
        Values of the free shape parameters (none for the kernel-driven models).
    fixed : mapping, optional
        Shape parameters held fixed, as for :func:`brdfcorr.fit.solver.fit_class_samples`.

    Returns
    -------
    dict of str to ndarray
        ``chi2_dof`` [sr^-2] (over N minus the linear terms and free shape parameters, as a fit's),
        ``r2`` [-], ``angular_r2`` [-], ``rmse`` [sr^-1], each (B,).
    """
    model, fixed, free = _resolve(model, fixed)
    profile = _profile(model, theta_i, theta_r, phi, brdf, fixed)
    design = profile.design(dict(shape or {}))
    coefficients = np.asarray(intensities, float).reshape(design.shape[1], -1)
    gram, cross = profile.products(design)
    ssr = profile.sum_yy - 2 * np.einsum("kb,kb->b", coefficients, cross) + np.einsum(
        "kb,kl,lb->b", coefficients, gram, coefficients)
    return _quality(profile, design, coefficients, np.maximum(ssr, 0.0), len(model.linear) + len(free))


def median_r2(
    model: str | Model, samples: Sequence, *, fixed: Mapping[str, float] | None = None, grid_points: int = 9,
    search_samples: int = 20_000,
) -> float:
    """How much of the data's variation a model explains: the median over bands of R^2 at the
    best shape, found on a seeded subsample of ``search_samples`` by the coarse grid and
    Nelder-Mead only (no Newton steps, no errors: cheap).

    Parameters
    ----------
    model : str or Model
        A surface model with intensity terms, as for :func:`brdfcorr.fit.solver.fit_class_samples`.
    samples : sequence of 4 array-likes
        ``(theta_i, theta_r, phi, brdf)``: solar zenith, view zenith and relative azimuth (N,)
        [deg] and BRDF (N, B) [sr^-1] of the class's samples.
    fixed, grid_points, search_samples :
        As for :func:`brdfcorr.fit.solver.fit_class_samples`.

    Returns
    -------
    float
        Median R^2 over the bands [-]; NaN when no band has one (constant bands).
    """
    model, fixed, free = _resolve(model, fixed)
    profile, shape = _coarse_shape(model, fixed, free, tuple(samples), search_samples, grid_points)
    r2 = profile.r2(profile.solve(profile.design(shape))[1])
    return float(np.nanmedian(r2)) if np.any(np.isfinite(r2)) else math.nan
