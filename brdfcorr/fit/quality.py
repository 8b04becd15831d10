"""How well a surface model explains a class's samples: R^2, angular R^2, RMS and chi^2/dof of
given weights (:func:`fit_quality`, e.g. a shape prior's posterior, :mod:`brdfcorr.fit.prior`),
from the sums of the solver's linear profile (:mod:`brdfcorr.fit.solver`). How well a model
predicts data it was not fitted on: :mod:`brdfcorr.fit.selection`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from brdfcorr.fit.profile import _profile
from brdfcorr.fit.shapes import _resolve
from brdfcorr.fit.solver import _absorbed, _quality, _repeated_only
from brdfcorr.fit.within import Levels
from brdfcorr.models import Model

__all__ = ["fit_quality"]


def fit_quality(model: str | Model, theta_i, theta_r, phi, brdf, intensities, *,
                shape: Mapping[str, float] | None = None, fixed: Mapping[str, float] | None = None,
                levels: Levels | None = None) -> dict[str, np.ndarray]:
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
    levels : Levels, optional
        The free levels the fit had (:mod:`brdfcorr.fit.within`): the quality is then that of the
        views within groups, each group's views at the level the given intensities give it at its
        own geometry, as the fit's last round judges its own solution; the constant term
        (f_iso, t0) is the level's.

    Returns
    -------
    dict of str to ndarray
        ``chi2_dof`` [sr^-2] (over N minus the linear terms, free shape parameters and free
        levels, as a fit's), ``r2`` [-], ``angular_r2`` [-], ``rmse`` [sr^-1], each (B,).
    """
    model, fixed, free = _resolve(model, fixed)
    shape = dict(shape or {})
    samples, _, levels = _repeated_only((theta_i, theta_r, phi, brdf), None, levels)
    profile = _profile(model, *samples, fixed, levels=levels)
    intensities = np.asarray(intensities, float).reshape(len(model.linear), -1)
    if levels is not None:
        group_model = levels.group_means(profile.raw_design(shape) @ intensities)
        profile = _profile(model, *samples, fixed, levels=levels, group_model=np.maximum(group_model, 1e-12))
    design = profile.design(shape)
    coefficients = intensities[profile.kept]
    gram, cross = profile.products(design)
    ssr = profile.sum_yy - 2 * np.einsum("kb,kb->b", coefficients, cross) + np.einsum(
        "kb,kl,lb->b", coefficients, gram, coefficients)
    return _quality(profile, design, coefficients, np.maximum(ssr, 0.0),
                    len(model.linear) + len(free) + _absorbed(levels))
