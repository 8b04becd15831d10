"""Sun/view geometry of a reflection: relative azimuth, facet inclination, specular deviation.

Conventions (``docs/conventions.md``): all angles in degrees. ``theta_i`` is the solar zenith, ``theta_r`` the
view zenith, both in [0, 90). Sun and view azimuths are the azimuths, clockwise from north, of the
directions from the pixel *towards* the sun and *towards* the sensor; the relative azimuth ``phi``
is their difference folded into [0, 180]. ``phi = 180`` is forward scattering: the specular
direction is ``theta_r = theta_i, phi = 180``.

In a frame with the surface normal along z and the sun in the x-z plane, the unit vectors towards
the sun and towards the sensor are

    i = (sin ti,          0,              cos ti)
    r = (sin tr cos phi,  sin tr sin phi, cos tr)

so that ``phi = 180, tr = ti`` gives the mirror direction ``m = (-sin ti, 0, cos ti)``,

and every angle here is an angle between two such vectors, evaluated with ``arctan2`` or a chord
(``2 arcsin(|a - b| / 2)``) rather than ``arccos``, which loses half its digits near 0.
The expressions are algebraically those of the papers (noted per function).

References
----------
.. [1] G. Meister, R. Wiemker, R. Monno, H. Spitzer, A. Strahler (1998): Investigation on the
   Torrance-Sparrow specular BRDF model. Proc. IGARSS'98, IV, 2095-2097.
.. [2] G. Meister, A. Rothkirch, H. Spitzer, J. Bienlein (2000): The shape of the specular peak of
   rough surfaces. Int. Arch. ISPRS XXXIII.
"""

from __future__ import annotations

import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any, TypeVar

import numpy as np

from brdfcorr._arrays import TINY, array_function, cosd, sind

__all__ = [
    "ScatteringGeometry",
    "relative_azimuth",
    "facet_inclination",
    "specular_deviation",
    "local_incidence",
]

_ZENITHS_DOC = """\
theta_i, theta_r : array-like
    Solar and view zenith angles [deg], in [0, 90)."""

#: numpydoc entries that the docstrings of the geometry, model and kernel functions share, by name:
#: the angle arguments and the results. :func:`_fill_doc` puts them where a docstring has a line
#: ``%(name)s``. ``angles`` states the relative azimuth as the specular models see it,
#: ``angles_backscattering`` as the kernel-driven models do (hot spot at ``phi = 0``).
_DOCS = {
    "zeniths": _ZENITHS_DOC,
    "angles": _ZENITHS_DOC + """
phi : array-like
    Relative azimuth [deg], in [0, 180]; 180 is forward scattering.""",
    "angles_backscattering": _ZENITHS_DOC + """
phi : array-like
    Relative azimuth [deg], in [0, 180]; 0 is backscattering, 180 forward scattering.""",
    "brdf": """\
brdf : array-like
    BRDF [sr^-1], same kind as the inputs (numpy, lazy dask, or xarray with broadcast dims).""",
    "kernel_value": """\
K : array-like
    Kernel value [-], same kind as the inputs; 0 at ``ti = tv = 0``.""",
}

_Function = TypeVar("_Function", bound=Callable)


def _fill_doc(function: _Function) -> _Function:
    """Replace each docstring line ``%(name)s`` by the entry ``name`` of :data:`_DOCS`, indented as
    that line (the docstring-template pattern of numpy, pandas and MNE). Apply it below
    :func:`~brdfcorr._arrays.array_function`, which copies the docstring."""
    if function.__doc__:  # None under python -OO
        function.__doc__ = re.sub(
            r"^( *)%\((\w+)\)s$",
            lambda line: textwrap.indent(_DOCS[line[2]], line[1]),
            function.__doc__,
            flags=re.MULTILINE,
        )
    return function


@dataclass(frozen=True, eq=False)
class ScatteringGeometry:
    """The angles of one reflection geometry (or an array of them), computed lazily and once.

    Models that need several geometric terms (the Torrance-Sparrow model needs the facet
    inclination, the local incidence on the facet and the cosines of both zeniths) take this object,
    so that a caller that evaluates many bands or classes at the same pixels computes the geometry
    only once. Each term is computed on first access and cached. Works on numpy and dask arrays.

    Parameters
    ----------
    theta_i : array-like
        Illumination (solar) zenith angle [deg], in [0, 90).
    theta_r : array-like
        View zenith angle [deg], in [0, 90).
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.
    """

    theta_i: Any
    theta_r: Any
    phi: Any

    @cached_property
    def cos_i(self):
        """cos(theta_i) [-]."""
        return cosd(self.theta_i)

    @cached_property
    def cos_r(self):
        """cos(theta_r) [-]."""
        return cosd(self.theta_r)

    @cached_property
    def _horizontal(self):
        # Horizontal components shared by the half vector i + r and by r - m (m = mirror of i):
        # both are (sin ti + sin tr cos phi, sin tr sin phi).
        sin_r = sind(self.theta_r)
        return sind(self.theta_i) + sin_r * cosd(self.phi), sin_r * sind(self.phi)

    @cached_property
    def _horizontal_norm(self):
        return np.hypot(*self._horizontal)

    @cached_property
    def alpha(self):
        """Facet inclination alpha [deg]: angle between the half vector and the surface normal."""
        return np.degrees(np.arctan2(self._horizontal_norm, self.cos_i + self.cos_r))

    @cached_property
    def cos_alpha(self):
        """cos(alpha) [-]."""
        return cosd(self.alpha)

    @cached_property
    def psi(self):
        """Specular deviation psi [deg]: angle between the view and the mirror direction."""
        chord = np.hypot(self._horizontal_norm, self.cos_r - self.cos_i)
        # |r - m| is at most 2; rounding can overshoot by an ulp, which arcsin would turn into NaN.
        return np.degrees(2.0 * np.arcsin(np.clip(0.5 * chord, 0.0, 1.0)))

    @cached_property
    def local_incidence(self):
        """Local incidence angle beta on the facet [deg]: half the angle between i and r."""
        sin_r = sind(self.theta_r)
        dx = sind(self.theta_i) - sin_r * cosd(self.phi)
        chord = np.hypot(np.hypot(dx, sin_r * sind(self.phi)), self.cos_i - self.cos_r)
        return np.degrees(np.arcsin(np.clip(0.5 * chord, 0.0, 1.0)))  # same ulp guard as psi

    @cached_property
    def cos_local(self):
        """cos(beta), the cosine of the local incidence angle on the facet [-]."""
        return cosd(self.local_incidence)

    @cached_property
    def shared(self) -> dict:
        """Further terms that models compute once per geometry and share, by name (the
        kernel-driven models' trigonometry, :mod:`brdfcorr.models.kernels`)."""
        return {}

    @cached_property
    def attenuation(self):
        """Torrance-Sparrow V-cavity masking/shadowing factor G [-] (purely geometric, so computed
        once per geometry; see :func:`brdfcorr.models.geometric_attenuation`)."""
        # Closed form (Blinn 1977): G = min(1, 2 cos a cos tr / cos b, 2 cos a cos ti / cos b).
        # cos b > 0 on the open domain; the floor keeps grazing geometries finite.
        steepest = np.minimum(self.cos_i, self.cos_r)
        return np.minimum(1.0, 2.0 * self.cos_alpha * steepest / np.maximum(self.cos_local, TINY))


@array_function("phi", "degree", "relative azimuth")
def relative_azimuth(saa, vaa):
    """Relative azimuth between the sun and the view direction, folded into [0, 180].

    Parameters
    ----------
    saa : array-like
        Azimuth of the direction from the pixel towards the sun [deg], clockwise from north.
    vaa : array-like
        Azimuth of the direction from the pixel towards the sensor [deg], clockwise from north.

    Returns
    -------
    phi : array-like
        ``|saa - vaa|`` folded into [0, 180] [deg]. 180 is forward scattering (sensor opposite the
        sun), 0 is backscattering (sensor on the sun's side, hot spot direction).

    Notes
    -----
    Products that store the azimuth of the sensor *as seen from the sensor* (pointing at the
    ground) differ from this convention by 180 deg; flip them explicitly before calling.
    """
    difference = np.abs(saa - vaa) % 360.0
    return np.minimum(difference, 360.0 - difference)


@array_function("alpha", "degree", "facet inclination")
def facet_inclination(theta_i, theta_r, phi):
    """Inclination alpha of the facet that reflects the sun specularly into the sensor.

    Parameters
    ----------
    theta_i : array-like
        Solar zenith angle [deg], in [0, 90).
    theta_r : array-like
        View zenith angle [deg], in [0, 90).
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 180 is forward scattering.

    Returns
    -------
    alpha : array-like
        Angle between the facet normal (the half vector of sun and view directions) and the
        surface normal [deg], in [0, 90).

    Notes
    -----
    Paper 003 [2]_, eq. 3 (after Ginneken et al. 1998)::

        cos a = (cos ti + cos tr) / sqrt((cos phi sin tr + sin ti)^2 + sin^2 phi sin^2 tr
                                         + (cos ti + cos tr)^2)

    evaluated as ``arctan2(horizontal, vertical)`` of the same vector for accuracy near 0.
    Examples from section 4 of [2]_: (45, 35, 180) -> 5.0 deg; (65, 65, 170) -> 10.6 deg.
    """
    return ScatteringGeometry(theta_i, theta_r, phi).alpha


@array_function("psi", "degree", "specular deviation")
@_fill_doc
def specular_deviation(theta_i, theta_r, phi):
    """Angle psi between the view direction and the specular (mirror) direction.

    Parameters
    ----------
    %(angles)s

    Returns
    -------
    psi : array-like
        Specular deviation [deg], in [0, 180]; 0 in the specular direction.

    Notes
    -----
    Paper 000 [1]_, eq. 2: ``cos psi = -sin ti sin tr cos phi + cos ti cos tr``, evaluated as the
    chord ``2 arcsin(|r - m| / 2)`` for accuracy near the peak. Example from [1]_:
    (40, 50, 180) -> 10 deg. In the principal plane ``psi = 2 alpha``.
    """
    return ScatteringGeometry(theta_i, theta_r, phi).psi


@array_function("beta", "degree", "local incidence angle on the facet")
@_fill_doc
def local_incidence(theta_i, theta_r, phi):
    """Local incidence angle beta of the sunlight on the specularly reflecting facet.

    Parameters
    ----------
    %(angles)s

    Returns
    -------
    beta : array-like
        Angle between the direction to the sun and the facet normal (half vector) [deg], in
        [0, 90); half the angle between the sun and view directions. This is the angle at which the
        Fresnel reflectance of the facet is evaluated (paper 003 [2]_, eq. 1).

    Notes
    -----
    ``cos(2 beta) = i . r = sin ti sin tr cos phi + cos ti cos tr``, evaluated as the chord
    ``arcsin(|i - r| / 2)``; in the specular direction ``beta = theta_i``.
    """
    return ScatteringGeometry(theta_i, theta_r, phi).local_incidence
