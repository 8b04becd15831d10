"""The errors of a class fit (:func:`_class_errors`): the joint sandwich covariance of the free
shape parameters and every band's intensities, with free levels the restored constant term and the
class's mean level (:func:`_with_levels`), the t-variance factor of few spatial blocks, and whether
the errors can be trusted (``errors_reliable``; ``docs/uncertainty.md``).
"""

from __future__ import annotations

import numpy as np

from brdfcorr.fit.identifiability import error_reliability, t_variance_factor
from brdfcorr.fit.profile import _LinearProfile
from brdfcorr.fit.sandwich import _joint_covariance
from brdfcorr.fit.shape_search import _at_edge, _room
from brdfcorr.fit.two_way import clustered_covariance, clustered_mean_variance
from brdfcorr.fit.within import with_constant, with_level_variance
from brdfcorr.models import Model

__all__: list[str] = []


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


def _with_levels(profile: _LinearProfile, shape: dict[str, float], coefficients, intensities, covariance, clusters):
    """The joint covariance of a fit with free levels (over the shape and
    :attr:`_LinearProfile.terms`) with the restored constant appended (:func:`_with_level`) and
    the uncertainty of the class's mean level, cluster-robust over ``clusters``
    (:func:`brdfcorr.fit.within.with_level_variance`)."""
    if profile.constant:
        covariance = _with_level(profile, shape, coefficients, covariance, clusters)
    joint = [*profile.kept, *([] if profile.constant_index is None else [profile.constant_index])]
    relative_variance = clustered_mean_variance(profile.level, clusters) / profile.scale**2
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
    variance = clustered_mean_variance(levels, clusters)
    return with_constant(covariance, np.stack(jacobian, axis=1), variance / means[index] ** 2)


def _class_errors(profile: _LinearProfile, shape: dict[str, float], design, coefficients, intensities, clusters):
    """The free parameters (model signature order), their covariance (B, p, p) and 1-sigma errors
    (B, p), and the diagnostics: ``at_edge``, ``error_dof``, ``n_clusters``, ``errors_reliable``,
    ``errors_reason``. ``coefficients`` are the intensities of the profile's terms (the design's
    columns), ``intensities`` every linear term's (with a restored constant, :func:`_with_level`).

    The covariance is the CR2 sandwich (:func:`brdfcorr.fit.sandwich._joint_covariance`; two-way
    over pixels and scenes for :class:`brdfcorr.fit.two_way.TwoWayClusters`) with each
    parameter's variance multiplied by the t-variance factor of its effective degrees of freedom
    (:func:`brdfcorr.fit.identifiability.t_variance_factor`; correlations unchanged), so that the
    pulls ``(fit - truth) / error`` have unit SD with few spatial blocks too; whether they can be
    trusted is :func:`brdfcorr.fit.identifiability.error_reliability` (``docs/uncertainty.md``).
    """
    model = profile.model
    sandwich = clustered_covariance(lambda labels: _joint_covariance(profile, shape, design, coefficients, labels),
                                    clusters)
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
    if sandwich.n_clusters < 2:  # one block: its residuals sum to ~0 at the fit, a covariance of ~0
        covariance = np.full_like(covariance, np.nan)  # none: no fit: block, a NaN 1-sigma
    deviations = np.sqrt(np.maximum(np.diagonal(covariance, axis1=1, axis2=2), 0.0))  # (B, p)
    at_edge = _at_edge(profile, shape)
    values = {**shape, **dict(zip(model.linear, intensities))}
    room = {name: _room(profile, name, np.asarray(values[name], dtype=float)) for name in names}
    # A shape parameter on a closed physical bound (RPV's rho_c = 0), which _at_edge leaves out: the
    # fits that end there are cut off, like the intensities _at_bound names.
    at_bound = _at_bound(model, intensities) + [f"{name} = {value:.4g}" for name, value in shape.items()
                                                if name not in at_edge and np.all(room[name] <= 0)]
    reliable, reason = error_reliability(names, error_dof, sandwich.n_clusters, sandwich.max_leverage,
                                         at_edge, at_bound, (room, deviations), scenes=sandwich.scenes)
    return names, covariance, deviations, {"at_edge": at_edge, "error_dof": error_dof,
                                           "n_clusters": sandwich.n_clusters, "errors_reliable": reliable,
                                           "errors_reason": reason}
