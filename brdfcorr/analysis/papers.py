"""The papers' own analyses of the specular BRDF models, as reusable functions.

- :func:`shadowing_impact`: how much the simplified Torrance-Sparrow (TS) model (G = 1) differs
  from the full model over a range of zeniths and azimuths, and where (paper 003, section 5).
- :func:`azimuthal_width`, :func:`width_reduction`: full width at half maximum in relative azimuth
  of the specular part of a BRDF, and its narrowing with illumination zenith (paper 003, fig. 3).
- :func:`albedo`: directional-hemispherical reflectance of any registered model by quadrature
  over the view hemisphere; :func:`specular_albedo_bound`, an energy bound of the TS specular part.

References
----------
.. [1] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII.
.. [2] G. Meister, R. Wiemker, R. Monno, H. Spitzer, A. Strahler (1998): Investigation on the
   Torrance-Sparrow specular BRDF model. Proc. IGARSS'98.
.. [3] F. E. Nicodemus (1970): Reflectance nomenclature and directional reflectance and
   emissivity. Applied Optics 9(6), 1474-1475.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from brdfcorr.errors import BrdfcorrWarning, ParameterError
from brdfcorr.fit.energy import hemispherical_integral
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import Model, get_model
from brdfcorr.models.torrance_sparrow import _fresnel

__all__ = [
    "SimplifiedModelWarning",
    "IntegrationAccuracyWarning",
    "ShadowingImpact",
    "shadowing_impact",
    "WORST_CASE_PARAMS",
    "PAPER_SHADOWING",
    "PAPER_SHADOWING_TEXT",
    "WIDTH_GEOMETRIES",
    "azimuthal_width",
    "width_reduction",
    "albedo",
    "specular_albedo_bound",
]


class SimplifiedModelWarning(BrdfcorrWarning):
    """The simplified TS model (G = 1) was used where paper 003 says it must not be (albedo)."""


class IntegrationAccuracyWarning(BrdfcorrWarning):
    """A numerical integral did not converge to the requested tolerance."""


# --------------------------------------------------------------------------------------------
# Shadowing impact (paper 003, section 5)
# --------------------------------------------------------------------------------------------

#: The worst case of paper 003, section 5: the specular peak of the roof tile (w = 0.035 as the
#: text rounds it) on a Lambertian component of albedo 0.01 (t0 = 0.01 / pi) [sr^-1, deg^-1, 1].
WORST_CASE_PARAMS = {"t0": 0.01 / math.pi, "t1": 0.20, "w": 0.035, "n": 1.77, "k": 0.25}

#: Maximum relative differences (simplified - full) / full that paper 003, section 5 states for
#: zeniths <= 70 deg and all azimuths, by material of the built-in library [-].
PAPER_SHADOWING = {
    "roof_tile": 0.103,
    "red_concrete": 0.010,
    "blue_concrete": 0.003,
    "red_aluminium": 0.001,  # "< 0.1 %"
}
#: The same as printed in paper 003.
PAPER_SHADOWING_TEXT = {
    "roof_tile": "10.3 %", "red_concrete": "1.0 %", "blue_concrete": "0.3 %", "red_aluminium": "< 0.1 %",
}


@dataclass(frozen=True)
class ShadowingImpact:
    """Largest differences between the simplified (G = 1) and the full TS model on a grid.

    Attributes
    ----------
    max_relative : float
        max of (f_simplified - f_full) / f_full [-] (>= 0 because G <= 1).
    where_relative : tuple of float
        (theta_i, theta_r, phi) [deg] of ``max_relative``; by reciprocity its mirror
        (theta_r, theta_i, phi) has the same value.
    max_absolute : float
        max of f_simplified - f_full [sr^-1].
    where_absolute : tuple of float
        (theta_i, theta_r, phi) [deg] of ``max_absolute``.
    max_zenith : float
        Largest zenith of the grid [deg]; both zeniths run over [0, max_zenith].
    phi_range : tuple of float
        (min, max) relative azimuth of the grid [deg].
    step : float
        Grid step [deg].
    """

    max_relative: float
    where_relative: tuple[float, float, float]
    max_absolute: float
    where_absolute: tuple[float, float, float]
    max_zenith: float
    phi_range: tuple[float, float]
    step: float


def _grid(start, stop, step):
    # Inclusive of both ends: paper 003 quotes maxima on the edge of its ranges.
    count = int(round((stop - start) / step)) + 1
    return np.linspace(start, stop, max(count, 2))


def shadowing_impact(params: Mapping[str, float], *, max_zenith: float = 70.0,
                     phi_range: tuple[float, float] = (0.0, 180.0), step: float = 0.5) -> ShadowingImpact:
    """Maximum relative and absolute difference between the simplified and the full TS model.

    Parameters
    ----------
    params : mapping
        Torrance-Sparrow parameters t0 [sr^-1], t1 [sr^-1], w [deg^-1], n [-], k [-].
    max_zenith : float, default 70
        Both zeniths run over [0, max_zenith] [deg], < 90.
    phi_range : (float, float), default (0, 180)
        Range of relative azimuth [deg] within [0, 180].
    step : float, default 0.5
        Grid step in all three angles [deg], > 0.

    Returns
    -------
    ShadowingImpact

    Notes
    -----
    Paper 003 [1]_, section 5 compares eq. 1 with and without the geometric attenuation factor:
    ``f_simplified - f_full = t1 F (1 - G) exp(-w^2 alpha^2) / (cos ti cos tr) >= 0``. It states, for
    the roof-tile peak on a Lambertian albedo of 0.01 (:data:`WORST_CASE_PARAMS`), 14 % and
    0.0019 sr^-1 for zeniths <= 65 deg (at theta_i = 0, theta_r = 65 deg), 34 % and 0.0044 sr^-1
    for zeniths <= 70 deg, and "no difference at all" for zeniths <= 60 deg; and for the Table-1
    samples 10.3 %, 1.0 %, 0.3 % and < 0.1 % (:data:`PAPER_SHADOWING`). With the 3-D V-cavity G
    of :func:`brdfcorr.models.geometric_attenuation`, G < 1 in backscatter and far from the
    principal plane even for zeniths <= 60 deg (G(60, 60, 0) = 0.5), so the last statement holds
    only near the forward principal plane (0 for phi >= 170 deg; the forward half phi >= 90 deg
    still gives 10.9 %, all azimuths 16.1 %). The 14 % is the model's value at (0, 65, 180) (13.7 %),
    not its maximum for zeniths <= 65 deg: 19.2 % over phi >= 90 deg, 24.4 % over all azimuths.
    See ``tests/analysis/test_analysis.py`` for the comparison.
    """
    model = get_model("torrance_sparrow")
    t0, t1, w, n, k = model.validate(params).values()
    if not (0.0 < step and 0.0 <= max_zenith < 90.0):
        raise ParameterError(f"shadowing_impact: need step > 0 and 0 <= max_zenith < 90, got {step}, {max_zenith}")
    phi_min, phi_max = phi_range
    if not 0.0 <= phi_min <= phi_max <= 180.0:
        raise ParameterError(f"shadowing_impact: phi_range {phi_range} must lie within [0, 180]")
    zeniths = _grid(0.0, max_zenith, step)
    phis = _grid(phi_min, phi_max, step)
    theta_r, phi = np.meshgrid(zeniths, phis, indexing="ij")
    # Per slab of theta_i: the largest relative and absolute difference and their geometry.
    best = {"relative": (-1.0, None), "absolute": (-1.0, None)}
    for theta_i in zeniths:  # one slab at a time keeps memory at len(zeniths) * len(phis)
        relative, gain = _shadowing_gain(ScatteringGeometry(theta_i, theta_r, phi), t0, t1, w, n, k)
        for key, values in (("relative", relative), ("absolute", gain)):
            index = np.unravel_index(np.argmax(values), values.shape)
            if values[index] > best[key][0]:
                where = (float(theta_i), float(theta_r[index]), float(phi[index]))
                best[key] = (float(values[index]), where)
    (max_relative, where_relative), (max_absolute, where_absolute) = best["relative"], best["absolute"]
    return ShadowingImpact(max_relative=max_relative, where_relative=where_relative, max_absolute=max_absolute,
                           where_absolute=where_absolute, max_zenith=float(max_zenith),
                           phi_range=(float(phi_min), float(phi_max)), step=float(step))


def _shadowing_gain(geometry: ScatteringGeometry, t0, t1, w, n, k) -> tuple[np.ndarray, np.ndarray]:
    """The simplified TS model's excess over the full one (paper 003, eq. 1 without and with G),
    relative [1] and absolute ``t1 F (1 - G) exp(-w^2 alpha^2) / (cos ti cos tr)`` [sr^-1]."""
    specular = (
        t1 * _fresnel(geometry.cos_local, n, k) * np.exp(-((w * geometry.alpha) ** 2))
        / (geometry.cos_i * geometry.cos_r)
    )
    attenuation = geometry.attenuation
    gain = specular * (1.0 - attenuation)  # f(G = 1) - f
    return gain / (t0 + specular * attenuation), gain


# --------------------------------------------------------------------------------------------
# Azimuthal width of the specular peak (paper 003, fig. 3)
# --------------------------------------------------------------------------------------------

#: (theta_i, theta_r) [deg] of the azimuthal cuts of paper 003, fig. 3.
WIDTH_GEOMETRIES = ((30.0, 30.0), (50.0, 50.0), (65.0, 70.0))


def _specular_part(model: Model, params: Mapping[str, float]):
    """The model with its Lambertian term t0 removed, as a function of (ti, tr, phi)."""
    params = model.validate(params)
    if "t0" in params:
        params = {**params, "t0": 0.0}
    return lambda theta_i, theta_r, phi: np.asarray(model(theta_i, theta_r, phi, **params), dtype=float)


def azimuthal_width(model, params: Mapping[str, float], theta_i: float, theta_r: float) -> float:
    """Full width at half maximum in relative azimuth of a model's specular part.

    Parameters
    ----------
    model : str or Model
        A registered model name (``"torrance_sparrow"``, ``"empirical"``, ...).
    params : mapping
        The model's parameters; t0, if the model has it, is dropped (the specular part is
        ``f - t0``, as paper 003 fig. 3 plots the measurements minus t0).
    theta_i, theta_r : float
        Illumination and view zenith of the cut [deg].

    Returns
    -------
    fwhm : float
        ``2 (180 - phi_half)`` [deg], with phi_half the relative azimuth below 180 at which the
        specular part falls to half its value at the peak (the cut is symmetric about
        phi = 180 because f(phi) = f(360 - phi)). ``inf`` if it never falls to half within
        [0, 180].

    Notes
    -----
    Paper 003 [1]_, fig. 3 and section 4: the azimuthal width of the TS peak narrows strongly with
    illumination zenith (by about 50 % from theta_i = theta_r = 30 to 50 deg and by about 75 % to
    theta_i = 65, theta_r = 70 deg), because the facet inclination needed to reflect a fixed
    azimuth offset grows with zenith (eq. 3: (30, 30, 170) -> 2.9 deg, (65, 65, 170) -> 10.6 deg).
    The peak is searched on a 0.1 deg grid and the half-maximum crossing refined by Brent's method.
    """
    specular = _specular_part(get_model(model), params)
    phis = np.linspace(0.0, 180.0, 1801)
    values = specular(theta_i, theta_r, phis)
    top = int(np.argmax(values))
    peak = values[top]
    if not peak > 0.0:
        raise ParameterError(
            f"azimuthal_width: the specular part of {get_model(model).name} is 0 at ({theta_i}, {theta_r})"
        )
    below = np.nonzero(values[: top + 1] < 0.5 * peak)[0]
    if below.size == 0:
        return math.inf
    left = below[-1]
    from scipy import optimize  # at first use: every chain imports this module, few call this

    phi_half = optimize.brentq(
        lambda p: float(specular(theta_i, theta_r, p)) - 0.5 * peak, phis[left], phis[left + 1], xtol=1e-10
    )
    return 2.0 * (180.0 - phi_half)


def width_reduction(model, params: Mapping[str, float], geometries=WIDTH_GEOMETRIES) -> dict:
    """Azimuthal widths at the cuts of paper 003 fig. 3 and their reduction relative to the first.

    Returns a dict with ``widths`` (FWHM [deg] per (theta_i, theta_r)) and ``reductions``
    (``1 - width / first width`` [-] per geometry; paper 003 states about 0.5 at (50, 50) and
    about 0.75 at (65, 70) relative to (30, 30)).
    """
    widths = {geometry: azimuthal_width(model, params, *geometry) for geometry in geometries}
    first = widths[geometries[0]]
    return {
        "widths": widths,
        "reductions": {geometry: 1.0 - width / first for geometry, width in widths.items()},
    }


# --------------------------------------------------------------------------------------------
# Directional-hemispherical reflectance (albedo)
# --------------------------------------------------------------------------------------------


def albedo(model, theta_i, params: Mapping[str, float], *, resolution: float = 2.0, order: int = 8,
           rtol: float = 1e-4):
    """Directional-hemispherical reflectance of a BRDF model by quadrature over the view hemisphere.

    Parameters
    ----------
    model : str or Model
        A registered model name or :class:`brdfcorr.models.Model`.
    theta_i : float or array-like
        Illumination zenith angle(s) [deg], in [0, 90).
    params : mapping
        The model's parameters (validated).
    resolution : float, default 2
        Width of the quadrature panels in view zenith and relative azimuth [deg], > 0.
    order : int, default 8
        Gauss-Legendre nodes per panel.
    rtol : float, default 1e-4
        If the result differs from the one with panels twice as wide by more than this [-], an
        :class:`IntegrationAccuracyWarning` is issued (the peak is too narrow for the panels).

    Returns
    -------
    rho : float or numpy.ndarray
        ``rho(theta_i) = int_hemisphere f(theta_i, theta_r, phi) cos(theta_r) dOmega_r`` [-]
        (Nicodemus [3]_), the fraction of the collimated irradiance reflected into the
        hemisphere; the shape of ``theta_i``.

    Warns
    -----
    SimplifiedModelWarning
        For ``torrance_sparrow_simplified``: paper 003 [1]_, section 5 says the simplified model
        must not be used for albedo, because zeniths above 70 deg matter there; without G the
        specular albedo grows like 1 / cos(theta_i) (see :func:`specular_albedo_bound`).

    Notes
    -----
    Composite Gauss-Legendre quadrature in theta_r (panel edges at 0, theta_i, 90 deg) and phi
    (edges at 0, 90, 150, 170, 180 deg), using ``f(phi) = f(-phi)``. A Lambertian ``f = t0`` gives
    ``pi t0`` to rounding.
    """
    model = get_model(model)
    params = model.validate(params)
    if model.name == "torrance_sparrow_simplified":
        warnings.warn("albedo of the simplified Torrance-Sparrow model (G = 1): paper 003 (section 5) says "
                      "not to use it for albedo; zeniths above 70 deg dominate there. Use torrance_sparrow.",
                      SimplifiedModelWarning, stacklevel=2)
    if not (resolution > 0 and int(order) >= 1):
        raise ParameterError(f"albedo: resolution [deg] must be > 0 and order >= 1, got {resolution}, {order}")
    theta_i = np.asarray(theta_i, dtype=float)
    if np.any((theta_i < 0) | (theta_i >= 90)) or not np.all(np.isfinite(theta_i)):
        raise ParameterError("albedo: theta_i must be in [0, 90) deg")
    brdf = lambda ti, tr, ph: np.asarray(model(ti, tr, ph, **params), dtype=float)  # noqa: E731
    results, worst = _albedo_with_error(brdf, theta_i, resolution, int(order))
    if worst > rtol:
        warnings.warn(f"albedo of {model.name}: panels of {resolution:g} and {2 * resolution:g} deg differ by "
                      f"{worst:.1e} (relative) > rtol = {rtol:g}; use a smaller resolution",
                      IntegrationAccuracyWarning, stacklevel=2)
    return results[()] if results.ndim == 0 else results


def _albedo_with_error(brdf, theta_i: np.ndarray, resolution: float, order: int) -> tuple[np.ndarray, float]:
    """The albedo [-] at each ``theta_i`` [deg] with panels of ``resolution`` [deg], and the largest
    relative difference from panels twice as wide (the quadrature's error estimate)."""
    results = np.empty(theta_i.shape)
    worst = 0.0
    for index, value in np.ndenumerate(theta_i):
        fine = hemispherical_integral(brdf, float(value), resolution, order)
        coarse = hemispherical_integral(brdf, float(value), 2.0 * resolution, order)
        worst = max(worst, abs(fine - coarse) / max(abs(fine), 1e-300))
        results[index] = fine
    return results, worst


def specular_albedo_bound(t1: float, w: float, fresnel_max: float = 1.0) -> float:
    """Upper bound, for every theta_i, of the albedo of the TS specular term (with G) [-].

    Parameters
    ----------
    t1 : float
        Intensity of the specular component [sr^-1].
    w : float
        Inverse width of the facet distribution [deg^-1].
    fresnel_max : float, default 1
        Upper bound of the Fresnel reflectance F [-].

    Returns
    -------
    bound : float
        ``8 t1 F_max int_(alpha < 90) exp(-w^2 alpha^2) cos(alpha) dOmega_h`` [-].

    Notes
    -----
    With dOmega_r = 4 cos(beta) dOmega_h (reflection about the half vector h), the specular albedo
    of paper 003 eq. 1 is ``(4 t1 / cos ti) int F G D(alpha) cos(beta) dOmega_h``; the shadowing
    branch of the V-cavity factor gives ``G cos(beta) <= 2 cos(alpha) cos(ti)``, so
    ``rho <= 8 t1 F_max int D cos(alpha) dOmega_h``, independent of theta_i. The simplified model
    (G = 1) has no such bound: its specular albedo grows like 1 / cos(theta_i).
    """
    scale = math.degrees(1.0)  # alpha in degrees inside the exponent

    def integrand(alpha):
        return math.exp(-((w * scale * alpha) ** 2)) * math.cos(alpha) * math.sin(alpha)

    from scipy import integrate  # at first use: every chain imports this module, few call this

    value, _ = integrate.quad(integrand, 0.0, 0.5 * math.pi, epsabs=0.0, epsrel=1e-10, limit=200)
    return 8.0 * t1 * fresnel_max * 2.0 * math.pi * value
