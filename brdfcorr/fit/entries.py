"""A class's imagery fit as a parameter-table entry (:func:`class_entry`): its parameters in
wavelength order, one value where every band shares it, with the ``fit:`` record of their
covariance (:class:`brdfcorr.params.FitRecord`), or its fallback's entry."""

from __future__ import annotations

import dataclasses

import numpy as np

from brdfcorr.fit.class_fit import ClassFit, compact
from brdfcorr.fit.settings import fallback_entry
from brdfcorr.params import ClassEntry

__all__ = ["class_entry", "compact", "record_source"]


def record_source(fit: ClassFit, source: str) -> str:
    """The ``source`` of a fitted class's ``fit:`` block: what was fitted, and its shape prior."""
    return source if fit.prior is None else f"{source} + shape prior {fit.prior}"


def _fit_record(fit: ClassFit, source: str, per_band: bool) -> dict | None:
    """The table's ``fit:`` block (:class:`brdfcorr.params.FitRecord`) of a fitted class: one
    matrix per band, or a single one when the parameters are band-independent. None when the
    covariance is not finite or has a negative variance (a table holds numbers only)."""
    source = record_source(fit, source)
    covariance = 0.5 * (fit.covariance + np.swapaxes(fit.covariance, 1, 2))
    variances = np.diagonal(covariance, axis1=1, axis2=2)
    if covariance.size == 0 or not np.all(np.isfinite(covariance)) or np.any(variances < 0):
        return None
    errors = np.sqrt(variances)
    flag = {"errors_reliable": fit.errors_reliable, "errors_reason": fit.errors_reason or None}
    if not per_band:
        return {"source": source, "parameters": list(fit.free), "n": fit.n_samples,
                "chi2_dof": float(fit.chi2_dof[0]), "r2": float(fit.r2[0]),
                "errors": {name: float(errors[0, j]) for j, name in enumerate(fit.free)},
                "covariance": covariance[0].tolist(), **flag}
    n_bands = covariance.shape[0]
    return {"source": source, "parameters": list(fit.free), "n": [fit.n_samples] * n_bands,
            "chi2_dof": np.asarray(fit.chi2_dof, float).tolist(), "r2": np.asarray(fit.r2, float).tolist(),
            "errors": {name: errors[:, j].tolist() for j, name in enumerate(fit.free)},
            "covariance": covariance.tolist(), **flag}


def _in_wavelength_order(fit: ClassFit, wavelengths):
    """The fit and the band wavelengths with the bands sorted by wavelength: a table lists its
    wavelengths increasing, an image may hold its bands in the sensor's order (MODIS: 645, 858,
    469, 2130 nm). Arrays with one entry per band are permuted alike."""
    if wavelengths is None or np.all(np.diff(np.asarray(wavelengths, float)) > 0):
        return fit, wavelengths
    order = np.argsort(np.asarray(wavelengths, float), kind="stable")

    def sort(values):
        values = np.asarray(values)
        return values[order] if values.ndim and values.shape[0] == order.size else values

    return dataclasses.replace(
        fit, params={name: sort(values) for name, values in fit.params.items()},
        errors={name: sort(values) for name, values in fit.errors.items()}, covariance=sort(fit.covariance),
        chi2_dof=sort(fit.chi2_dof), r2=sort(fit.r2), rmse=sort(fit.rmse), angular_r2=sort(fit.angular_r2),
    ), np.asarray(wavelengths, float)[order]


def class_entry(fit: ClassFit, wavelengths, source: str, bad_bands: list[list[float]] | None = None):
    """The table entry of a class fit (:class:`brdfcorr.params.ClassEntry`): its parameters
    per band in wavelength order with their ``fit:`` record, its fallback's entry, or None for a
    class left uncorrected."""
    fit, wavelengths = _in_wavelength_order(fit, wavelengths)
    if fit.status == "uncorrected":
        return None
    if fit.status == "fallback":
        return ClassEntry(**fallback_entry(fit.fallback, fit.class_id, fit.name), bad_bands=bad_bands)
    params = {name: compact(values) for name, values in fit.params.items()}
    per_band = any(isinstance(value, list) for value in params.values())
    if not per_band and fit.covariance.shape[0] > 1 and np.any(fit.covariance != fit.covariance[:1]):
        # Equal values in every band but not equal errors: the table keeps one value per band.
        params = {name: np.asarray(values, float).tolist() if name in fit.free else params[name]
                  for name, values in fit.params.items()}
        per_band = True
    return ClassEntry(
        id=fit.class_id,
        name=fit.name,
        model=fit.model,
        params=params,
        wavelengths=[float(w) for w in wavelengths] if per_band and wavelengths is not None else None,
        fit=_fit_record(fit, source, per_band),
        bad_bands=bad_bands,
    )
