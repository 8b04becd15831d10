"""The Rahman-Pinty-Verstraete (RPV) BRDF model, with its hot-spot term.

Conventions
-----------
Angles in degrees; ``theta_i`` solar and ``theta_r`` view zenith in [0, 90), ``phi`` the relative
azimuth in [0, 180] with brdfcorr's ``phi = 0`` backscattering and ``phi = 180`` forward
scattering. The phase angle g is the angle between the directions towards the sun and towards the
sensor, ``cos g = cos ti cos tv + sin ti sin tv cos phi`` [1]_, so g = 0 at the hot spot
(``tv = ti, phi = 0``), where also G = 0. With ``+2 Theta cos g`` in the Henyey-Greenstein
function (Rahman et al. write ``-2 Theta cos(pi - g)``, the same), Theta < 0 makes backward
scattering dominate and Theta > 0 forward scattering.

The RAMI-IV benchmark's RPV tables [3]_ measure the relative azimuth the other way round
(their 180 is brdfcorr's 0); ``tests/models/test_kernels.py`` reproduces them with that conversion.

References
----------
.. [1] H. Rahman, B. Pinty, M. M. Verstraete (1993): Coupled surface-atmosphere reflectance (CSAR)
   model 2. Semiempirical surface model usable with NOAA Advanced Very High Resolution
   Radiometer data. JGR 98(D11), 20791-20801.
.. [2] B. Pinty, F. Roveda, M. M. Verstraete, N. Gobron, Y. Govaerts, J. V. Martonchik,
   D. J. Diner, R. A. Kahn (2000): Surface albedo retrieval from Meteosat 1. Theory. JGR 105(D14),
   18099-18112 (the RPV model with a separate hot-spot parameter rho_c).
.. [3] RAMI-IV (J.-L. Widlowski et al. 2013, JGR Atmospheres 118): the RPV BRF tables of its
   anisotropic backgrounds, rami-benchmark.jrc.ec.europa.eu, ``.../ANISOTROPIC_BACKGROUND/
   MISCELLANEOUS/rpv_*.dat``.
"""

from __future__ import annotations

import numpy as np

from brdfcorr._arrays import TINY
from brdfcorr.geometry import ScatteringGeometry, _fill_doc
from brdfcorr.models._base import MAX_INTENSITY, Model, Parameter
from brdfcorr.models.kernels import _angles

__all__ = ["rpv", "RPV"]

# Bounds keep the model finite on [0, 90) deg: with k in (0, 2] the Minnaert term is at most
# 1 / (cos ti cos tv (cos ti + cos tv)) < 1e47, the Henyey-Greenstein term at most
# 2 / (1 - |theta|)^2 < 2e32 for |theta| < 1 (0 at |theta| = 1), the hot-spot term 2; with
# rho0 <= MAX_INTENSITY the model stays below 1e83 in float64 (a float32 correction flags the
# overflow of such extreme parameters as nodata, brdfcorr.correction).
RHO0 = Parameter(
    "rho0", "sr^-1", 0.03, 0.0, MAX_INTENSITY,
    description="amplitude; the RPV reflectance-factor amplitude rho_0 divided by pi",
)
K = Parameter(
    "k", "1", 0.75, 0.0, upper=2.0, lower_open=True,
    description="Minnaert-like exponent: < 1 bowl-shaped (brighter towards grazing), > 1 bell-shaped, "
    "1 flat",
)
THETA = Parameter(
    "theta", "1", -0.1, -1.0, upper=1.0,
    description="Henyey-Greenstein asymmetry: < 0 backward, > 0 forward scattering dominates "
    "(|theta| = 1 is the degenerate limit: the model is 0 except in one direction)",
)
RHO_C = Parameter(
    "rho_c", "1", 0.1, 0.0, upper=1.0,
    description="hot-spot parameter: 1 is no hot spot, smaller a stronger one (factor up to "
    "2 - rho_c); pi rho0 gives the 3-parameter model of Rahman et al.",
)


def _rpv_shape(geometry: ScatteringGeometry, k, theta, rho_c):
    """``rpv / rho0``: the basis function of the amplitude."""
    angles = _angles(geometry)
    shared = geometry.shared
    if "rpv_geometry" not in shared:
        cos_i, cos_r = angles.cos_i, angles.cos_r
        # cos ti cos tv (cos ti + cos tv) > 0 on [0, 90); the floor keeps a grazing edge finite.
        product = np.maximum(cos_i * cos_r * (cos_i + cos_r), TINY)
        # G^2 = tan^2 ti + tan^2 tv - 2 tan ti tan tv cos phi, as a sum of non-negative terms.
        tan_i, tan_r = angles.tan_i, angles.tan_r
        distance = np.sqrt((tan_i - tan_r) ** 2 + 2.0 * tan_i * tan_r * angles.one_minus_cos_phi)
        shared["rpv_geometry"] = (product, distance)
    product, distance = shared["rpv_geometry"]

    minnaert = product ** (k - 1.0)
    # 1 + 2 Theta cos g + Theta^2 = (1 - |Theta|)^2 + 2 |Theta| (1 + sign(Theta) cos g): a sum of
    # non-negative terms, accurate near the direction where it vanishes for |Theta| -> 1.
    one_minus_cos_g = angles.one_minus_cos_xi
    toward = np.where(np.less(theta, 0.0), one_minus_cos_g, 2.0 - one_minus_cos_g)
    magnitude = np.abs(theta)
    base = (1.0 - magnitude) ** 2 + 2.0 * magnitude * toward
    henyey_greenstein = (1.0 - theta**2) / np.maximum(base**1.5, TINY)
    hotspot = 1.0 + (1.0 - rho_c) / (1.0 + distance)
    return minnaert * henyey_greenstein * hotspot


def _rpv_kernel(geometry: ScatteringGeometry, rho0, k, theta, rho_c):
    return rho0 * _rpv_shape(geometry, k, theta, rho_c)


def _rpv_basis(geometry: ScatteringGeometry, k, theta, rho_c):
    return (_rpv_shape(geometry, k, theta, rho_c),)


RPV = Model(
    name="rpv",
    description="Rahman-Pinty-Verstraete: Minnaert term x Henyey-Greenstein x hot spot, with a separate "
    "hot-spot parameter rho_c",
    reference="Rahman, Pinty & Verstraete (1993), JGR 98(D11); Pinty et al. (2000), JGR 105(D14)",
    parameters=(RHO0, K, THETA, RHO_C),
    kernel=_rpv_kernel,
    linear=("rho0",),
    basis=_rpv_basis,
)


@_fill_doc
def rpv(theta_i, theta_r, phi, rho0, k, theta, rho_c):
    """Rahman-Pinty-Verstraete BRDF with a separate hot-spot parameter.

    Parameters
    ----------
    %(zeniths)s
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 0 is backscattering (the hot spot is at
        ``theta_r = theta_i, phi = 0``), 180 forward scattering.
    rho0 : array-like
        Amplitude [sr^-1], >= 0. The RPV literature states the model as a reflectance factor
        (BRF = pi BRDF): divide its rho_0 by pi. The model is linear in rho0.
    k : array-like
        Minnaert-like exponent [-], in (0, 2]: k < 1 gives a bowl shape (brighter towards grazing
        angles, typical of vegetation), k > 1 a bell shape, k = 1 no such term. The upper bound
        2 is a generous limit of this library, not of the model.
    theta : array-like
        Asymmetry of the Henyey-Greenstein function [-], in [-1, 1]: < 0 backward scattering
        dominates (most land surfaces), > 0 forward scattering. At |theta| = 1 the function is 0
        except in one direction (the model is finite but degenerate there).
    rho_c : array-like
        Hot-spot parameter [-], in [0, 1]. The hot-spot factor ``1 + (1 - rho_c) / (1 + G)`` is
        ``2 - rho_c`` at the hot spot and tends to 1 away from it, so 1 means no hot spot and
        smaller values a stronger one (values above 1 would make a dark spot, which is not
        allowed). Rahman et al. (1993) [1]_ tie it to the amplitude (``rho_c = pi rho0``, their
        3-parameter model); here it is a separate parameter as in Pinty et al. (2000) [2]_ and
        RAMI, which keeps the model linear in rho0.

    Returns
    -------
    %(brdf)s

    Raises
    ------
    brdfcorr.errors.ParameterError
        For NaN or out-of-range parameters.

    Notes
    -----
    Rahman et al. (1993) [1]_, with the separate hot-spot parameter of [2]_::

        f = rho0 M(ti, tv; k) F(g; theta) H(G; rho_c)
        M = (cos ti cos tv (cos ti + cos tv))^(k - 1)
        F = (1 - theta^2) / (1 + 2 theta cos g + theta^2)^(3/2)
        H = 1 + (1 - rho_c) / (1 + G)
        cos g = cos ti cos tv + sin ti sin tv cos phi
        G = sqrt(tan^2 ti + tan^2 tv - 2 tan ti tan tv cos phi)

    The model is reciprocal. With ``k = 1, theta = 0, rho_c = 1`` it is Lambertian, ``f = rho0``.

    Examples
    --------
    >>> float(rpv(35.0, 20.0, 60.0, rho0=0.1, k=1.0, theta=0.0, rho_c=1.0))
    0.1
    """
    return RPV(theta_i, theta_r, phi, rho0=rho0, k=k, theta=theta, rho_c=rho_c)
