"""The empirical specular-peak model, the Gaussian facet peak of paper 000, and a Lambertian model.

References
----------
.. [1] G. Meister, R. Wiemker, R. Monno, H. Spitzer, A. Strahler (1998): Investigation on the
   Torrance-Sparrow specular BRDF model. Proc. IGARSS'98, IV, 2095-2097.
"""

from __future__ import annotations

import math

import numpy as np

from brdfcorr.geometry import ScatteringGeometry, _fill_doc
from brdfcorr.models._base import MAX_INTENSITY, Model, Parameter

__all__ = ["empirical", "specular_peak", "lambertian", "EMPIRICAL", "SPECULAR_PEAK", "LAMBERTIAN"]

# Bounds keep the model finite on [0, 90) deg: a, t0 <= MAX_INTENSITY (see there). The b term
# exp(b (ti tr)^2) takes ti tr < (pi/2)^2, so b <= 10 rad^-4 gives at most exp(60.9) = 2.8e26 (times
# a: 2.8e29, within float32); the paper's b is ~1 (b = 1e308 overflows). A very negative b or a
# large c only makes the peak underflow to 0.
A = Parameter("a", "sr^-1", 0.05, 0.0, MAX_INTENSITY, description="intensity of the specular peak")
B = Parameter(
    "b", "rad^-4", 1.0, -math.inf, 10.0,
    description="shift of the peak towards large zeniths; ~1.0 for a constant Fresnel reflectance",
)
C = Parameter("c", "deg^-1", 0.05, 0.0, lower_open=True, description="inverse width of the specular peak")
T0 = Parameter("t0", "sr^-1", 0.0, 0.0, MAX_INTENSITY, description="Lambertian (diffuse) component")
SIGMA = Parameter(
    "sigma", "deg", 0.07, 0.0, lower_open=True, description="standard deviation of the Gaussian peak"
)


def _peak(geometry: ScatteringGeometry, b, c):
    # Paper 000, eq. 5: the b term takes the zeniths in radians, the c term psi in degrees.
    zenith_product = np.radians(geometry.theta_i) * np.radians(geometry.theta_r)
    return np.exp(b * zenith_product**2) * np.exp(-((c * geometry.psi / 2.0) ** 2))


def _empirical_kernel(geometry: ScatteringGeometry, a, b, c, t0):
    return t0 + a * _peak(geometry, b, c)


def _empirical_basis(geometry: ScatteringGeometry, b, c):
    return _peak(geometry, b, c), 1.0


EMPIRICAL = Model(
    name="empirical",
    description="empirical specular peak a exp(b (ti tr)^2) exp(-c^2 (psi/2)^2) plus a Lambertian term",
    reference="Meister et al. (1998), eq. 5",
    parameters=(A, B, C, T0),
    kernel=_empirical_kernel,
    linear=("a", "t0"),
    basis=_empirical_basis,
)


@_fill_doc
def empirical(theta_i, theta_r, phi, a, b, c, t0=0.0):
    """Empirical specular-peak BRDF of paper 000 (eq. 5), plus an optional Lambertian term.

    Parameters
    ----------
    %(angles)s
    a : array-like
        Intensity of the peak [sr^-1], >= 0.
    b : array-like
        Shift of the peak towards large zenith angles [rad^-4]. About 1.0 for a constant Fresnel
        reflectance; a fitted b > 1 indicates a Fresnel reflectance rising with zenith, b much
        smaller than 1 a problem with the inversion [1]_.
    c : array-like
        Inverse width of the peak [deg^-1], > 0. In the principal plane psi = 2 alpha, so c plays
        the role of w of the Torrance-Sparrow model.
    t0 : array-like, default 0
        Lambertian component [sr^-1], >= 0 (not part of eq. 5; 0 gives the paper's model).

    Returns
    -------
    brdf : array-like
        BRDF [sr^-1], same kind as the inputs.

    Notes
    -----
    Paper 000 [1]_, eq. 5, with psi the specular deviation of eq. 2
    (:func:`brdfcorr.geometry.specular_deviation`)::

        f = t0 + a exp(b (theta_i theta_r)^2) exp(-c^2 (psi / 2)^2)

    theta in radians in the b term, psi in degrees in the c term.
    """
    return EMPIRICAL(theta_i, theta_r, phi, a=a, b=b, c=c, t0=t0)


def _specular_peak_kernel(geometry: ScatteringGeometry, sigma):
    # Paper 000, eq. 3 with the reciprocity fix 1/sqrt(cos ti cos tr); the Gaussian is normalized
    # over psi in radians, so that for small sigma it integrates to 1 over psi.
    sigma_rad = np.radians(sigma)
    gaussian = np.exp(-0.5 * (geometry.psi / sigma) ** 2) / (math.sqrt(2.0 * math.pi) * sigma_rad)
    return gaussian / np.sqrt(geometry.cos_i * geometry.cos_r)


SPECULAR_PEAK = Model(
    name="specular_peak",
    description="Gaussian 'perfect' specular peak of a smooth facet, reciprocal form",
    reference="Meister et al. (1998), eq. 3",
    parameters=(SIGMA,),
    kernel=_specular_peak_kernel,
)


@_fill_doc
def specular_peak(theta_i, theta_r, phi, sigma):
    """Gaussian approximation of a perfect specular peak (paper 000, eq. 3), reciprocal form.

    Parameters
    ----------
    %(angles)s
    sigma : array-like
        Standard deviation of the Gaussian in the specular deviation psi [deg], > 0. Paper 000
        used 0.07 deg (and 0.03 deg for its smoothest surface) as the facet BRDF of its V-cavity
        simulation.

    Returns
    -------
    brdf : array-like
        ``exp(-psi^2 / (2 sigma^2)) / (sqrt(2 pi) sigma sqrt(cos ti cos tr))`` [sr^-1 up to the
        normalization of a delta function], with sigma in radians in the normalization.

    Notes
    -----
    Paper 000 [1]_, eq. 3 replaces the 1/cos(theta_r) of a delta-like peak by
    1/sqrt(cos ti cos tr) so that the function obeys Helmholtz reciprocity; for a sharp peak
    (theta_i ~ theta_r wherever it is not ~0) the two are the same.
    """
    return SPECULAR_PEAK(theta_i, theta_r, phi, sigma=sigma)


def _lambertian_kernel(geometry: ScatteringGeometry, t0):
    # Broadcast the constant to the shape (and array kind) of all three angles: alpha uses each.
    return t0 + 0.0 * geometry.alpha


LAMBERTIAN = Model(
    name="lambertian",
    description="Lambertian (isotropic) reflector: f = t0; its albedo is pi t0",
    reference="Meister et al. (2000), eq. 1 with t1 = 0",
    parameters=(T0,),
    kernel=_lambertian_kernel,
    linear=("t0",),
    basis=lambda geometry: (1.0,),
)


def lambertian(theta_i, theta_r, phi, t0):
    """Lambertian BRDF ``f = t0`` [sr^-1], broadcast to the angles (a reference for checks)."""
    return LAMBERTIAN(theta_i, theta_r, phi, t0=t0)
