"""Ray-tracing-like simulation of a surface of specular V-cavities (paper 000).

Paper 000 [1]_ checks the analytic Torrance-Sparrow (TS) model [2]_ with an independent numerical
simulation of the same surface: long symmetric V-grooves whose facets reflect with a narrow
Gaussian "perfect" specular peak (its eq. 3), masking and shadowing computed exactly from the groove
cross-section for single scattering, and the contributions summed over every facet inclination
alpha and orientation Phi, weighted by the TS facet distribution exp(-w^2 alpha^2). This module is
that simulation.

The surface
-----------
Every facet is one side of a symmetric V-groove; its opposite side has the same inclination and
the opposite orientation (Phi + 180). Facets with normal (alpha, Phi) cover an area
``D(alpha) dOmega_n = exp(-w^2 alpha^2) dOmega_n`` per unit macroscopic area (alpha in degrees,
dOmega_n the solid angle of facet normals), the distribution of TS. The BRDF of the surface is the
flux reflected by all lit-and-visible facet area, per unit macroscopic area and per irradiance
(Nicodemus' definition, paper 000 eq. 1)::

    f(i, r) = sum_n D(alpha_n) dOmega_n f_facet(n; i, r) (n.i) (n.r) g(n; i, r) / (cos ti cos tr)

with ``f_facet`` the Gaussian specular peak of paper 000 eq. 3 in the facet's own frame
(:func:`brdfcorr.models.specular_peak`), times a Fresnel reflectance F(n.i) if requested, and
``g`` the fraction of the facet that is both illuminated and visible, found by intersecting the
rays through the ridge of the opposite facet with the facet in the groove's cross-section.

The result is divided by the albedo of the facet peak, ``sqrt(2 pi) sigma`` (sigma in radians;
the integral of eq. 3 times cos over the view hemisphere for a small sigma), so that it does not
scale with sigma. The TS analysis then predicts, for sigma -> 0,
``f = F G D(alpha) / (4 cos ti cos tr)``: :func:`brdfcorr.models.torrance_sparrow` with t0 = 0 and
t1 = 1/4 (the 1/4 is the Jacobian between facet normals and reflected directions). Paper 000
compares shapes only, normalized at ti = tr = 45, phi = 180 (``normalize=True``).

Accuracy and time
-----------------
The sum runs over a fixed grid of facet normals: rings of constant alpha spaced ``step`` degrees,
each ring divided into cells of about ``step`` degrees of arc (cell solid angles exact). The facet
peak has a width sigma in the reflected direction, i.e. sigma / 2 in the facet normal, so the grid
must resolve sigma / 2: ``step`` is given as a fraction of sigma (``step_fraction`` of the
:class:`FacetGrid`, with ``cutoff`` and ``pole``). Only grid
cells whose normal lies within ``cutoff`` standard deviations of the facet peak of the half vector
contribute more than ``exp(-cutoff^2 / 2)`` of the peak value; the others are skipped (an
omission bounded by that factor, not an approximation of the physics). Paper 000 notes that the
accuracy depends on this grid; ``benchmarks/bench_simulate.py`` prints the error against the
analytic model and the time per geometry for several settings. Measured at the geometries of
paper 000, fig. 2 (normalized TS value > 0.1): step = sigma / 2 (default) 0.16 %, step = sigma
3 % (aliasing of the sampled Gaussian), step = 1.5 sigma 60 %; a grid with its pole at the zenith
3 % at the specular point even at step = sigma / 2. The remaining 0.16 % is not a grid error: the
facet peak of finite width sigma blurs the kink of the masking/shadowing factor, a bias
proportional to sigma (0.6 %, 0.23 %, 0.09 % for sigma = 0.14, 0.07, 0.035 deg). The time is
about 1-2 ms per geometry, mostly fixed overhead; it grows as 1 / step_fraction^2.

References
----------
.. [1] G. Meister, R. Wiemker, R. Monno, H. Spitzer, A. Strahler (1998): Investigation on the
   Torrance-Sparrow specular BRDF model. Proc. IGARSS'98, IV, 2095-2097.
.. [2] K. Torrance, E. Sparrow (1967): Theory for off-specular reflection from roughened surfaces.
   J. Opt. Soc. Am. 57(9), 1105-1114.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from brdfcorr.errors import ParameterError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import get_model
from brdfcorr.models.torrance_sparrow import _fresnel

__all__ = [
    "paper_sigma",
    "facet_visible_fraction",
    "simulate_vcavity",
    "FacetGrid",
    "NORMALIZATION_GEOMETRY",
]

#: Geometry (theta_i, theta_r, phi) [deg] at which paper 000, fig. 2 normalizes every curve.
NORMALIZATION_GEOMETRY = (45.0, 45.0, 180.0)

_SPECULAR_PEAK = get_model("specular_peak")


@dataclass(frozen=True)
class FacetGrid:
    """The grid of facet normals that :func:`simulate_vcavity` sums over: its accuracy and cost.

    The defaults are the accurate setting of the module notes (0.16 % at the geometries of paper
    000, fig. 2); :func:`simulate_vcavity` checks the values.

    Attributes
    ----------
    step_fraction : float, default 0.5
        Grid step of facet normals as a fraction of sigma [-], > 0 (the step is
        ``step_fraction * sigma`` degrees). Smaller is more accurate and slower; see the module
        notes and ``benchmarks/bench_simulate.py``.
    cutoff : float, default 5
        Facet normals farther than ``cutoff`` peak standard deviations from the half vector are
        skipped [-], > 0; they would contribute less than ``exp(-cutoff^2 / 2)`` of the peak.
    pole : {"horizontal", "zenith"}, default "horizontal"
        Axis of the latitude-longitude grid of facet normals. "zenith" is the plain (alpha, Phi)
        grid of rings of constant inclination; its pole alpha = 0 is the half vector of every
        specular geometry, where the sum has an O(step^2) error (about 3 % at the default
        step). "horizontal" puts the pole on the horizon, perpendicular to the principal plane,
        where no half vector lies; the sum is then accurate everywhere.
    """

    step_fraction: float = 0.5
    cutoff: float = 5.0
    pole: Literal["horizontal", "zenith"] = "horizontal"


def paper_sigma(w: float) -> float:
    """Width sigma [deg] of the facet peak that paper 000 used for a roughness w [deg^-1].

    0.07 deg for w = 0.01 and 0.05 deg^-1, 0.03 deg for the smooth w = 0.15 deg^-1 (section
    "Ray-tracing validation" of [1]_); here 0.03 deg for w >= 0.1 deg^-1.
    """
    return 0.03 if w >= 0.1 else 0.07


def facet_visible_fraction(direction_u, direction_z, alpha):
    """Fraction of a V-groove facet that a direction reaches unobstructed, by 2-D ray intersection.

    Parameters
    ----------
    direction_u, direction_z : array-like
        Components of the unit direction (towards the sun or the sensor) in the groove's
        cross-section plane [-]: along the horizontal azimuth of the facet normal, and along the
        surface normal.
    alpha : array-like
        Facet inclination [deg], in [0, 90).

    Returns
    -------
    fraction : array-like
        Unobstructed fraction of the facet's width [-], in [0, 1]; 0 for a facet facing away.

    Notes
    -----
    In the cross-section the facet runs from the groove bottom O = (0, 0) to its ridge
    T = (-cos a, sin a) (unit width; its normal (sin a, cos a) faces the opposite facet, which runs
    from O to R = (cos a, sin a)). A point s T of the facet sees the direction d unobstructed iff
    the ray from it passes above the opposite ridge R. The boundary point s0 T lies on the line
    through R along d: ``s0 T + t d = R`` gives ``s0 = cross(R, d) / cross(T, d)``; the part
    s in [s0, 1] is unobstructed. (Its closed form, ``min(1, 2 cos a d_z / (n.d))``, is the
    V-cavity term of Torrance & Sparrow [2]_; here it is computed from the construction.)
    """
    a = np.radians(alpha)
    ridge_u, ridge_z = np.cos(a), np.sin(a)  # R, the ridge of the opposite facet
    top_u, top_z = -np.cos(a), np.sin(a)  # T, the ridge of this facet
    facing = direction_u * np.sin(a) + direction_z * np.cos(a)  # n.d in the cross-section
    cross_r = ridge_u * direction_z - ridge_z * direction_u
    cross_t = top_u * direction_z - top_z * direction_u  # = -facing, < 0 for a facing facet
    # Only facing facets (cross_t < 0) are evaluated; the floor keeps the others finite.
    boundary = cross_r / np.minimum(cross_t, -1e-300)
    return np.where(facing > 0.0, 1.0 - np.clip(boundary, 0.0, 1.0), 0.0)


def _unit_vectors(theta_i, theta_r, phi):
    ti, tr, ph = np.radians(theta_i), np.radians(theta_r), np.radians(phi)
    incident = np.array([math.sin(ti), 0.0, math.cos(ti)])
    view = np.array([math.sin(tr) * math.cos(ph), math.sin(tr) * math.sin(ph), math.cos(tr)])
    return incident, view


#: Orthonormal bases (e1, e2, pole) of the two facet-normal grids; see :func:`simulate_vcavity`.
_GRID_BASES = {
    # Pole on the horizon, perpendicular to the principal plane: the grid's singular points are
    # vertical facets, which are never the half vector of two directions above the horizon.
    "horizontal": (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
    # Pole at the zenith: rings of constant facet inclination alpha. Its singular point alpha = 0
    # is the half vector of every specular geometry (theta_i = theta_r, phi = 180).
    "zenith": (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])),
}


def _window_cells(half_vector, radius, step, pole):
    """Grid cells of facet normals near ``half_vector``: unit normals and cell solid angles [sr].

    The global grid is a latitude-longitude grid around the ``pole`` axis: rings at colatitude
    chi_j = (j + 1/2) step, j = 0 .. ceil(180 / step) - 1, ring j divided into
    n_j = max(1, round(360 sin(chi_j) / step)) equal cells of exact solid angle. Only the cells
    within about ``radius`` [deg] of the half vector and facing upwards are returned.
    """
    e1, e2, axis = _GRID_BASES[pole]
    chi_h = math.degrees(math.acos(float(np.clip(half_vector @ axis, -1.0, 1.0))))
    lambda_h = math.degrees(math.atan2(half_vector @ e2, half_vector @ e1))
    n_rings = math.ceil(180.0 / step)
    first = max(0, math.floor((chi_h - radius) / step) - 1)
    last = min(n_rings - 1, math.ceil((chi_h + radius) / step) + 1)
    # Largest longitude difference of a cap of this radius around the half vector (all of it when
    # the cap contains a pole of the grid).
    sin_chi_h = math.sin(math.radians(chi_h))
    if radius < min(chi_h, 180.0 - chi_h):
        lambda_radius = math.degrees(math.asin(min(1.0, math.sin(math.radians(radius)) / sin_chi_h)))
    else:
        lambda_radius = 180.0
    normals, solid_angles = [], []
    for j in range(first, last + 1):
        lower, upper = j * step, min((j + 1) * step, 180.0)
        chi = math.radians(0.5 * (lower + upper))
        n_cells = max(1, round(360.0 * math.sin(chi) / step))
        width = 360.0 / n_cells
        if lambda_radius + width >= 180.0:
            k = np.arange(n_cells)
        else:
            k = np.arange(
                math.floor((lambda_h - lambda_radius) / width) - 1,
                math.ceil((lambda_h + lambda_radius) / width) + 2,
            )
        longitude = np.radians((k + 0.5) * width)
        normals.append(
            math.sin(chi) * (np.cos(longitude)[:, None] * e1 + np.sin(longitude)[:, None] * e2)
            + math.cos(chi) * axis
        )
        # Exact solid angle of a cell: (cos lower - cos upper) dlambda.
        ring = math.cos(math.radians(lower)) - math.cos(math.radians(upper))
        solid_angles.append(np.full(k.size, ring * math.radians(width)))
    normals, solid_angles = np.concatenate(normals), np.concatenate(solid_angles)
    upward = normals[:, 2] > 0.0
    return normals[upward], solid_angles[upward]


def _simulate_one(theta_i, theta_r, phi, w, sigma, step, cutoff, n, k, pole):
    incident, view = _unit_vectors(theta_i, theta_r, phi)
    half = incident + view
    half /= np.linalg.norm(half)
    cos_beta = float(incident @ half)
    # The facet peak is sigma wide in the reflected direction; the mirror direction turns by
    # 2 dn within the plane of incidence and by 2 cos(beta) dn across it.
    radius = cutoff * sigma / (2.0 * max(cos_beta, 1e-3))
    normal, solid_angle = _window_cells(half, radius, step, pole)
    cos_i_local = normal @ incident
    cos_r_local = normal @ view
    front = (cos_i_local > 0.0) & (cos_r_local > 0.0)
    if not np.any(front):
        return 0.0
    normal, solid_angle = normal[front], solid_angle[front]
    cos_i_local, cos_r_local = cos_i_local[front], cos_r_local[front]
    # Facet inclination alpha [deg] and the horizontal unit vector u of the groove cross-section
    # (the azimuth Phi of the normal; any horizontal direction for a horizontal facet).
    horizontal = np.linalg.norm(normal[:, :2], axis=1)
    alpha = np.degrees(np.arctan2(horizontal, normal[:, 2]))
    groove_u = normal[:, :2] / np.maximum(horizontal, 1e-300)[:, None]

    # Local angles of the facet's own frame: zeniths from the facet normal, relative azimuth
    # between the projections of i and r onto the facet plane.
    tangential_i = incident - cos_i_local[:, None] * normal
    tangential_r = view - cos_r_local[:, None] * normal
    theta_i_local = np.degrees(np.arctan2(np.linalg.norm(np.cross(incident, normal), axis=1), cos_i_local))
    theta_r_local = np.degrees(np.arctan2(np.linalg.norm(np.cross(view, normal), axis=1), cos_r_local))
    phi_local = np.degrees(
        np.arctan2(
            np.linalg.norm(np.cross(tangential_i, tangential_r), axis=1),
            np.einsum("ij,ij->i", tangential_i, tangential_r),
        )
    )
    peak = _SPECULAR_PEAK.kernel(
        ScatteringGeometry(theta_i_local, theta_r_local, phi_local), sigma=sigma
    )
    if n is not None:
        peak = peak * _fresnel(cos_i_local, n, k)

    lit = facet_visible_fraction(groove_u @ incident[:2], incident[2], alpha)
    seen = facet_visible_fraction(groove_u @ view[:2], view[2], alpha)
    # Both unobstructed parts are the upper parts of the facet: their overlap is the smaller one.
    lit_and_seen = np.minimum(lit, seen)

    density = np.exp(-((w * alpha) ** 2))
    flux = np.sum(density * solid_angle * peak * cos_i_local * cos_r_local * lit_and_seen)
    facet_albedo = math.sqrt(2.0 * math.pi) * math.radians(sigma)
    return flux / (incident[2] * view[2] * facet_albedo)


def _checked_settings(w, sigma, grid: FacetGrid, n, k) -> float:
    """The peak's sigma [deg] (:func:`paper_sigma` of ``w`` by default), after checking that ``w``
    [deg^-1], sigma and the grid's step fraction and cutoff are finite and > 0, and n, k
    (unless n is None) valid refractive indices (:class:`ParameterError` otherwise)."""
    for name, value in (("w", w), ("step_fraction", grid.step_fraction), ("cutoff", grid.cutoff)):
        if not (np.isfinite(value) and value > 0):
            raise ParameterError(f"simulate_vcavity: {name} = {value!r} must be finite and > 0")
    sigma = paper_sigma(w) if sigma is None else sigma
    if not (np.isfinite(sigma) and sigma > 0):
        raise ParameterError(f"simulate_vcavity: sigma = {sigma!r} [deg] must be finite and > 0")
    if n is not None:
        get_model("torrance_sparrow").parameter("n").check(n, "simulate_vcavity")
        get_model("torrance_sparrow").parameter("k").check(k, "simulate_vcavity")
    return sigma


def simulate_vcavity(theta_i, theta_r, phi, w, *, sigma=None, grid: FacetGrid = FacetGrid(), n=None, k=0.0,
                     normalize=False):
    """Simulated specular BRDF of a surface of symmetric V-cavities (paper 000).

    Parameters
    ----------
    theta_i, theta_r : array-like
        Illumination and view zenith angles [deg], in [0, 90).
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.
    w : float
        Inverse width of the facet inclination distribution exp(-w^2 alpha^2) [deg^-1], > 0
        (c of paper 000).
    sigma : float, optional
        Standard deviation of the Gaussian facet peak (paper 000, eq. 3) [deg], > 0. Default:
        :func:`paper_sigma` (0.07 deg, 0.03 deg for w >= 0.1 deg^-1).
    grid : FacetGrid, default FacetGrid()
        Grid of facet normals: step as a fraction of sigma [-] (default 0.5), cutoff in peak
        standard deviations [-] (default 5) and pole ("horizontal", default, or "zenith"). A
        finer grid is more accurate and slower; see the module notes and
        ``benchmarks/bench_simulate.py``.
    n, k : float, optional
        Complex refractive index of the facets [-]. ``n=None`` (default) is a constant Fresnel
        reflectance F = 1, as in paper 000.
    normalize : bool, default False
        Divide by the simulated value at theta_i = theta_r = 45, phi = 180 deg, as paper 000,
        fig. 2 does (same settings).

    Returns
    -------
    brdf : numpy.ndarray or float
        Simulated BRDF per unit facet albedo [sr^-1] (dimensionless if ``normalize``), with the
        broadcast shape of the angles. For sigma -> 0 the TS analysis predicts
        ``torrance_sparrow(theta_i, theta_r, phi, t0=0, t1=1/4, w=w, n=..., k=...)`` (with n very
        large for F = 1).

    Notes
    -----
    See the module docstring for the surface, the sum and the accuracy/time trade-off. The cost
    is about ``(2 grid.cutoff / grid.step_fraction)^2`` facet normals per geometry, independent
    of w.
    """
    step_fraction, cutoff, pole = grid.step_fraction, grid.cutoff, grid.pole
    sigma = _checked_settings(w, sigma, grid, n, k)
    theta_i, theta_r, phi = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (theta_i, theta_r, phi)))
    if np.any((theta_i < 0) | (theta_i >= 90) | (theta_r < 0) | (theta_r >= 90)):
        raise ParameterError("simulate_vcavity: zenith angles must be in [0, 90) deg")
    if pole not in _GRID_BASES:
        raise ParameterError(f"simulate_vcavity: pole = {pole!r} must be one of {', '.join(_GRID_BASES)}")
    step = step_fraction * sigma
    settings = (w, sigma, step, cutoff, n, k, pole)
    result = np.array(
        [_simulate_one(ti, tr, ph, *settings) for ti, tr, ph in zip(theta_i.flat, theta_r.flat, phi.flat)]
    ).reshape(theta_i.shape)
    if normalize:
        result = result / _simulate_one(*NORMALIZATION_GEOMETRY, *settings)
    return result[()] if result.ndim == 0 else result
