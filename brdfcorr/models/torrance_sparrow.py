"""The Torrance-Sparrow specular BRDF model, its Fresnel and masking/shadowing terms.

References
----------
.. [1] K. Torrance, E. Sparrow (1967): Theory for off-specular reflection from roughened surfaces.
   J. Opt. Soc. Am. 57(9), 1105-1114.
.. [2] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII.
.. [3] J. F. Blinn (1977): Models of light reflection for computer synthesized pictures.
   SIGGRAPH '77, 192-198 (closed form of the V-cavity attenuation of [1]_ in three dimensions).
.. [4] M. Born, E. Wolf: Principles of Optics, section 14.2 (reflection at an absorbing medium).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from brdfcorr._arrays import TINY, array_function
from brdfcorr.geometry import ScatteringGeometry, _fill_doc
from brdfcorr.models._base import MAX_INTENSITY, Model, Parameter

__all__ = [
    "fresnel",
    "geometric_attenuation",
    "torrance_sparrow",
    "mean_facet_inclination",
    "TORRANCE_SPARROW",
    "TORRANCE_SPARROW_SIMPLIFIED",
]

# Bounds keep the model finite on [0, 90) deg: the specular term F G exp(-w^2 alpha^2) /
# (cos ti cos tr) is at most 1.6e31, so t0, t1 <= MAX_INTENSITY (see there). w needs no upper bound
# (exp(-(w alpha)^2) only underflows to 0). The Fresnel formula takes (n^2 - k^2 - sin^2)^2 and
# 4 n^2 k^2, which overflow for n or k above ~1e77 (n = 1e308 is an internal error): n, k <= 1e10
# keep them below 1e41, far above any material (n < 10, k < 100 even for metals in the infrared)
# yet above n = 1e8, the "very large n" that makes F a constant 1 (paper 000's facets).
MAX_INDEX = 1e10
T0 = Parameter("t0", "sr^-1", 0.02, 0.0, MAX_INTENSITY, description="Lambertian (diffuse) component")
T1 = Parameter("t1", "sr^-1", 0.5, 0.0, MAX_INTENSITY, description="intensity of the specular component")
W = Parameter(
    "w", "deg^-1", 0.05, 0.0, lower_open=True,
    description="inverse width of the Gaussian facet-inclination distribution exp(-w^2 alpha^2)",
)
N = Parameter(
    "n", "1", 1.5, 0.0, MAX_INDEX, lower_open=True,
    description="real part of the refractive index of the facets",
)
K = Parameter(
    "k", "1", 0.25, 0.0, MAX_INDEX,
    description="imaginary part (absorption) of the refractive index; paper 003 fixes it at 0.25",
)
TS_PARAMETERS = (T0, T1, W, N, K)


def _fresnel(cos_local, n, k):
    # Unpolarized reflectance of n + ik at incidence cos_local, in the real form of [4]_:
    # a^2 - b^2 = n^2 - k^2 - sin^2, a^2 b^2 = n^2 k^2.
    cos_local = np.clip(cos_local, 0.0, 1.0)
    sin2 = 1.0 - cos_local**2
    excess = n**2 - k**2 - sin2
    root = np.sqrt(excess**2 + 4.0 * n**2 * k**2)
    # root >= |excess|; the maximum only absorbs rounding below zero.
    a = np.sqrt(np.maximum(0.5 * (root + excess), 0.0))
    b2 = np.maximum(0.5 * (root - excess), 0.0)
    # Denominators vanish only at grazing incidence on a matched index (n = 1, k = 0).
    r_s = ((a - cos_local) ** 2 + b2) / np.maximum((a + cos_local) ** 2 + b2, TINY)
    # r_p / r_s, multiplied through by cos^2 so that grazing incidence needs no tan().
    ratio = ((a * cos_local - sin2) ** 2 + b2 * cos_local**2) / np.maximum(
        (a * cos_local + sin2) ** 2 + b2 * cos_local**2, TINY
    )
    return 0.5 * r_s * (1.0 + ratio)


@array_function("fresnel", "1", "unpolarized Fresnel reflectance")
def fresnel(cos_local, n, k=0.0):
    """Unpolarized Fresnel reflectance of a facet with complex refractive index n + ik.

    Parameters
    ----------
    cos_local : array-like
        Cosine of the local incidence angle on the facet [-], in [0, 1]; see
        :func:`brdfcorr.geometry.local_incidence`.
    n : array-like
        Real part of the refractive index [-], finite and > 0. A very large n gives F -> 1
        (constant Fresnel reflectance).
    k : array-like, default 0
        Imaginary part (extinction coefficient) [-], >= 0.

    Returns
    -------
    F : array-like
        Reflectance [-], in [0, 1]; the mean of the s- and p-polarized reflectances.

    Notes
    -----
    With ``a^2 - b^2 = n^2 - k^2 - sin^2 beta`` and ``a^2 b^2 = n^2 k^2`` (Born & Wolf [4]_)::

        R_s = ((a - cos b)^2 + b^2) / ((a + cos b)^2 + b^2)
        R_p = R_s ((a cos b - sin^2 b)^2 + b^2 cos^2 b) / ((a cos b + sin^2 b)^2 + b^2 cos^2 b)
        F   = (R_s + R_p) / 2

    At normal incidence ``F = ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2)``. Used in paper 003 [2]_, eq. 1.
    """
    N.check(n, "fresnel")
    K.check(k, "fresnel")
    return _fresnel(cos_local, n, k)


@array_function("G", "1", "geometric attenuation factor (V-cavity masking/shadowing)")
@_fill_doc
def geometric_attenuation(theta_i, theta_r, phi):
    """Torrance-Sparrow geometric attenuation factor G of symmetric V-cavities, in 3-D.

    Parameters
    ----------
    %(angles)s

    Returns
    -------
    G : array-like
        Fraction of the specularly reflecting facets that is both illuminated and visible [-], in
        [0, 1]. G = 1 in the specular direction and wherever both zeniths are <= 45 deg; beyond
        that it can be smaller away from the forward principal plane (G(50, 50, 0) = 0.826,
        G(60, 60, 0) = 0.5).

    Notes
    -----
    Torrance & Sparrow [1]_ assume long symmetric V-cavities whose axis is perpendicular to the
    plane containing the surface normal N and the facet normal H (the half vector of the sun
    direction L and the view direction V). Masking and shadowing then depend only on the
    projections of L and V onto that plane, which gives, for any azimuth (Blinn [3]_)::

        G = min(1, 2 (N.H)(N.V) / (V.H), 2 (N.H)(N.L) / (V.H))
          = min(1, 2 cos(alpha) cos(theta_r) / cos(beta), 2 cos(alpha) cos(theta_i) / cos(beta))

    with alpha the facet inclination and beta the local incidence angle (V.H = L.H = cos beta).
    This is the factor of paper 003 [2]_, eq. 1 (their figs. 4 and 5 show it in the principal plane).
    """
    return ScatteringGeometry(theta_i, theta_r, phi).attenuation


def _specular_term(geometry: ScatteringGeometry, w, n, k, *, shadowing: bool = True):
    # Paper 003, eq. 1; the facet distribution exp(-w^2 alpha^2) takes alpha in degrees (eq. 2).
    specular = _fresnel(geometry.cos_local, n, k) * np.exp(-((w * geometry.alpha) ** 2))
    if shadowing:
        specular = specular * geometry.attenuation
    return specular / (geometry.cos_i * geometry.cos_r)


def _ts_kernel(geometry: ScatteringGeometry, t0, t1, w, n, k, *, shadowing: bool):
    return t0 + t1 * _specular_term(geometry, w, n, k, shadowing=shadowing)


def _ts_basis(geometry: ScatteringGeometry, w, n, k, *, shadowing: bool):
    return 1.0, _specular_term(geometry, w, n, k, shadowing=shadowing)


def _ts_model(name: str, description: str, reference: str, *, shadowing: bool) -> Model:
    """The Torrance-Sparrow model with or without the masking/shadowing factor G."""
    return Model(
        name=name,
        description=description,
        reference=reference,
        parameters=TS_PARAMETERS,
        kernel=functools.partial(_ts_kernel, shadowing=shadowing),
        linear=("t0", "t1"),
        basis=functools.partial(_ts_basis, shadowing=shadowing),
    )


TORRANCE_SPARROW = _ts_model(
    "torrance_sparrow",
    "Torrance-Sparrow: Lambertian + specular peak with Fresnel and V-cavity masking/shadowing",
    "Meister et al. (2000), eq. 1; Torrance & Sparrow (1967)",
    shadowing=True,
)

TORRANCE_SPARROW_SIMPLIFIED = _ts_model(
    "torrance_sparrow_simplified",
    "simplified Torrance-Sparrow (G = 1): no masking/shadowing; safe for zeniths <= 70 deg",
    "Meister et al. (2000), section 5",
    shadowing=False,
)


def torrance_sparrow(theta_i, theta_r, phi, t0, t1, w, n, k, shadowing=True):
    """Torrance-Sparrow BRDF: a Lambertian term plus the specular peak of rough surfaces.

    Parameters
    ----------
    theta_i : array-like
        Solar (illumination) zenith angle [deg], in [0, 90).
    theta_r : array-like
        View zenith angle [deg], in [0, 90).
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.
    t0 : array-like
        Lambertian component [sr^-1], >= 0.
    t1 : array-like
        Intensity of the specular component [sr^-1], >= 0.
    w : array-like
        Inverse width of the facet inclination distribution [deg^-1], > 0.
    n : array-like
        Real refractive index of the facets [-], > 0.
    k : array-like
        Absorption coefficient (imaginary refractive index) [-], >= 0.
    shadowing : bool, default True
        Include the V-cavity geometric attenuation factor G. False gives the simplified model of
        paper 003, section 5 (G = 1): for zeniths <= 70 deg it differs by at most ~10 % for the
        Table-1 roof tile (the roughest surface measured there) and, for a rough peak over a dark
        (albedo 0.01) background, by up to 34 % in the forward half (phi >= 90 deg, paper 003's
        figure) and 38 % over all azimuths; it must not be used for albedo.

    Returns
    -------
    brdf : array-like
        Bidirectional reflectance distribution function [sr^-1]; same kind as the inputs
        (numpy, lazy dask, or xarray with broadcast dims).

    Raises
    ------
    brdfcorr.errors.ParameterError
        (a ValueError) for NaN or out-of-range parameters (w <= 0, n <= 0, k < 0, ...).

    Notes
    -----
    Paper 003 [2]_, eq. 1::

        f = t0 + t1 F(beta; n, k) G(theta_i, theta_r, phi) exp(-w^2 alpha^2) / (cos ti cos tr)

    with alpha the facet inclination [deg] (:func:`brdfcorr.geometry.facet_inclination`, eq. 3),
    beta the local incidence angle on the facet, F the unpolarized Fresnel reflectance
    (:func:`fresnel`) and G the V-cavity masking/shadowing factor (:func:`geometric_attenuation`).
    The model is reciprocal: f(ti, tr, phi) = f(tr, ti, phi).

    Examples
    --------
    The roof tile of paper 003, Table 1, in the specular direction at 45 deg:

    >>> round(float(torrance_sparrow(45, 45, 180, 0.0245, 0.20, 0.0362, 1.77, 0.25)), 4)
    0.0633
    """
    model = TORRANCE_SPARROW if shadowing else TORRANCE_SPARROW_SIMPLIFIED
    return model(theta_i, theta_r, phi, t0=t0, t1=t1, w=w, n=n, k=k)


def mean_facet_inclination(w):
    """Mean facet inclination |alpha| [deg] of the distribution P(alpha) ~ exp(-w^2 alpha^2).

    Parameters
    ----------
    w : array-like
        Inverse width [deg^-1], > 0.

    Returns
    -------
    array-like
        ``1 / (w sqrt(pi))`` [deg], the mean of |alpha| under the half-Gaussian of paper 003 [2]_,
        eq. 2; the "average surface normals" quoted in its section 4 (15.6 deg for the roof tile).
    """
    W.check(w, "mean_facet_inclination")
    return 1.0 / (w * math.sqrt(math.pi))
