"""Synthetic goniometer measurements: the geometries of an EGO-like campaign and a model's BRDF
at them with multiplicative noise, as :class:`~brdfcorr.fit.measurements.Measurements` (for
examples, tests and planning a campaign: which geometries tell a model's parameters apart)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from brdfcorr.errors import MeasurementError
from brdfcorr.fit.measurements import Measurements
from brdfcorr.models import get_model

__all__ = ["goniometer_angles", "synthesize_measurements"]


def goniometer_angles(
    theta_i: Sequence[float] = (30.0, 50.0, 65.0),
    *,
    max_view: float = 75.0,
    view_step: float = 5.0,
    azimuth_cuts: Sequence[tuple[float, float]] = ((30.0, 30.0), (50.0, 50.0), (65.0, 70.0), (65.0, 50.0)),
    azimuth_step: float = 5.0,
):
    """Goniometer-like measurement angles: principal plane and azimuthal cuts, as at the EGO.

    Parameters
    ----------
    theta_i : sequence of float
        Lamp zenith angles of the principal-plane scans [deg] (paper 003: 30, 50, 65).
    max_view, view_step : float
        The principal-plane scans run over view zeniths 0, step, ..., ``max_view`` [deg] on the
        forward side (phi = 180) and the backward side (phi = 0).
    azimuth_cuts : sequence of (theta_i, theta_r)
        Fixed zenith pairs [deg] scanned in azimuth (paper 003, fig. 3: (30, 30), (50, 50), (65, 70)).
    azimuth_step : float
        The azimuth scans run over phi = 0, step, ..., 180 - step [deg] (180 is in the principal
        plane scan already).

    Returns
    -------
    theta_i, theta_r, phi : numpy.ndarray
        1-D arrays [deg]. With the defaults: 237 geometries, 120 of them with phi >= 90 (paper 003
        fitted 122-145 such measurements a sample).
    """
    view = np.arange(0.0, max_view + 0.5 * view_step, view_step)
    rows = []
    for zenith in theta_i:
        rows += [(zenith, view_zenith, 180.0) for view_zenith in view]
        rows += [(zenith, view_zenith, 0.0) for view_zenith in view if view_zenith > 0]
    azimuths = np.arange(0.0, 180.0 - 0.5 * azimuth_step, azimuth_step)
    for zenith, view_zenith in azimuth_cuts:
        rows += [(zenith, view_zenith, azimuth) for azimuth in azimuths]
    angles = np.array(rows, dtype=float)
    return angles[:, 0], angles[:, 1], angles[:, 2]


def synthesize_measurements(
    model,
    params: dict[str, float],
    theta_i,
    theta_r,
    phi,
    *,
    relative_noise: float = 0.04,
    seed: int | None = 0,
    source: str = "synthetic",
    wavelength: float | None = None,
) -> Measurements:
    """Simulated goniometer measurements of a model with Gaussian relative noise.

    Parameters
    ----------
    model : str or brdfcorr.models.Model
        A registered model name or model.
    params : dict of str to float
        Its parameters (e.g. ``load_material("roof_tile").params``).
    theta_i, theta_r, phi : array-like
        Measurement geometry [deg], e.g. from :func:`goniometer_angles`.
    relative_noise : float
        1-sigma relative error of each measurement [-]; paper 003 reports total errors of 4-15 %.
        0 gives exact model values (with sigma = 0 not allowed, sigma is then None).
    seed : int or None
        Seed of :func:`numpy.random.default_rng`; fixed by default so results repeat.
    source : str
        Description stored in the result.
    wavelength : float, optional
        Wavelength [nm] recorded with every measurement.

    Returns
    -------
    Measurements
        ``brdf = f (1 + relative_noise * N(0, 1))`` with ``f`` the model BRDF [sr^-1], negative draws
        clipped to 0, and ``sigma = relative_noise * f`` (the true error, so that a weighted fit
        is unbiased).
    """
    model = get_model(model)
    truth = np.asarray(model(theta_i, theta_r, phi, **params), dtype=float)
    if relative_noise < 0:
        raise MeasurementError(f"{source}: relative_noise must be >= 0, got {relative_noise:g}")
    rng = np.random.default_rng(seed)
    brdf = np.clip(truth * (1.0 + relative_noise * rng.standard_normal(truth.shape)), 0.0, None)
    sigma = relative_noise * truth if relative_noise > 0 else None
    return Measurements(theta_i, theta_r, phi, brdf, sigma, source=source, wavelength=wavelength)
