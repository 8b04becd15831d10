"""Energy conservation of a fitted BRDF: its directional-hemispherical reflectance (albedo) by
quadrature over the view hemisphere (:func:`hemispherical_integral`, also the engine of
:func:`brdfcorr.analysis.papers.albedo`), and the message of a fit whose albedo exceeds 1 at a
measured illumination zenith (:func:`albedo_excess`), which no passive surface can have: most
often measurements in percent or given as reflectance factors (pi * BRDF) instead of BRDF [sr^-1].

A check of the measured values alone would not be sound: a BRDF has no pointwise bound (a glossy
sample's peak is many times 1/pi sr^-1, a mirror's a delta), only its cosine-weighted integral over
the hemisphere has one, so the check is made on the fitted model, which fills in the hemisphere.

References
----------
.. [1] F. E. Nicodemus (1970): Reflectance nomenclature and directional reflectance and
   emissivity. Applied Optics 9(6), 1474-1475.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["hemispherical_integral", "albedo_excess", "ENERGY_RESOLUTION", "ENERGY_ZENITHS"]

#: Quadrature panels [deg] of the check after a fit: within 1e-4 of 2-deg panels on paper 003's
#: materials (the aluminium's narrow peak included), at about 2 ms per illumination zenith.
ENERGY_RESOLUTION = 10.0
#: At most this many illumination zeniths are checked (evenly spaced over the measured range where
#: there are more: the albedo varies smoothly with theta_i).
ENERGY_ZENITHS = 12


def _panels(breaks, max_width):
    """Split the intervals between ``breaks`` into panels no wider than ``max_width``."""
    edges = [breaks[0]]
    for lower, upper in zip(breaks[:-1], breaks[1:]):
        if upper > lower:
            count = max(1, math.ceil((upper - lower) / max_width - 1e-9))
            edges.extend(np.linspace(lower, upper, count + 1)[1:])
    return np.asarray(edges)


def _gauss_legendre(edges, order):
    """Nodes and weights of composite Gauss-Legendre quadrature over panels ``edges``."""
    x, weight = np.polynomial.legendre.leggauss(order)
    lower, upper = edges[:-1, None], edges[1:, None]
    half = 0.5 * (upper - lower)
    return ((lower + upper) / 2 + half * x).ravel(), (half * weight).ravel()


def hemispherical_integral(brdf: Callable, theta_i: float, resolution: float, order: int) -> float:
    """``rho(theta_i) = int_hemisphere f(theta_i, theta_r, phi) cos(theta_r) dOmega_r`` [-] of
    ``brdf(theta_i, theta_r, phi)`` [sr^-1] (angles in degrees) at one illumination zenith [deg], by
    composite Gauss-Legendre quadrature: panels no wider than ``resolution`` [deg] with ``order``
    nodes, edges at 0, theta_i and 90 deg in theta_r and at 0, 90, 150, 170 and 180 deg in phi."""
    # rho = 2 int_0^pi dphi int_0^pi/2 f cos(tr) sin(tr) dtr (f is even in phi about 0 and 180).
    # Panel edges at the specular zenith and clustered towards phi = 180 resolve the peak.
    theta_edges = _panels([0.0, theta_i, 90.0], resolution)
    phi_edges = _panels([0.0, 90.0, 150.0, 170.0, 180.0], resolution)
    theta_r, weight_theta = _gauss_legendre(theta_edges, order)
    phi, weight_phi = _gauss_legendre(phi_edges, order)
    # broadcast_to: a constant model (lambertian) may return the shape of theta_i only.
    values = np.broadcast_to(brdf(theta_i, theta_r[:, None], phi[None, :]), (theta_r.size, phi.size))
    kernel = np.cos(np.radians(theta_r)) * np.sin(np.radians(theta_r)) * weight_theta
    return 2.0 * math.radians(1.0) ** 2 * float(kernel @ values @ weight_phi)


def albedo_excess(name: str, brdf: Callable, theta_i) -> str | None:
    """The warning of a fitted BRDF that reflects more than it receives, or None.

    Parameters
    ----------
    name : str
        The model's name, for the message.
    brdf : callable
        ``brdf(theta_i, theta_r, phi)`` [sr^-1] of the fitted model (angles [deg]; a
        :meth:`~brdfcorr.fit.results.FitResult.predict`).
    theta_i : array-like
        The measured illumination zeniths [deg] (at most :data:`ENERGY_ZENITHS` distinct ones are
        checked).

    Returns
    -------
    str or None
        Where the albedo exceeds 1 at some zenith: the largest, where, and what the measurements
        would give as reflectance factors (divided by pi) or in percent (by 100).
    """
    zeniths = np.unique(np.asarray(theta_i, dtype=float))
    if zeniths.size > ENERGY_ZENITHS:
        zeniths = np.linspace(zeniths[0], zeniths[-1], ENERGY_ZENITHS)
    with np.errstate(all="ignore"):
        albedo = np.array([hemispherical_integral(brdf, float(zenith), ENERGY_RESOLUTION, 8) for zenith in zeniths])
    albedo = np.where(np.isfinite(albedo), albedo, -np.inf)  # a model that overflows says nothing here
    worst = int(np.argmax(albedo)) if albedo.size else 0
    if not albedo.size or albedo[worst] <= 1.0:
        return None
    value = float(albedo[worst])
    return (f"{name}: the fitted BRDF reflects more light than it receives: albedo (its integral of BRDF cos(theta_r) "
            f"over the hemisphere) {value:.3g} > 1 at theta_i = {zeniths[worst]:g} deg, which no surface can have. "
            f"Are the values reflectance factors (pi * BRDF: divided by pi the albedo is {value / math.pi:.3g}) or "
            f"in percent (divided by 100: {value / 100:.3g})? The fit expects BRDF [sr^-1]")
