"""Kernel-driven (Ross-Li) BRDF models, as used by the MODIS BRDF/albedo product (MCD43).

A kernel-driven model is a linear combination of an isotropic term and two kernels that depend on
the geometry only [1]_ [2]_::

    f(ti, tr, phi) = f_iso + f_vol K_vol(ti, tr, phi) + f_geo K_geo(ti, tr, phi)

``K_vol`` describes volume scattering by a layer of leaves (Ross-Thick for a dense, Ross-Thin for
a sparse layer; after Ross 1981 and Roujean et al. [3]_), ``K_geo`` the geometric-optical
shadowing of a surface covered with spheroidal crowns (Li-Sparse for sparse, Li-Dense for dense
crowns; after Li & Strahler 1992). MODIS uses Ross-Thick Li-Sparse-Reciprocal ("RTLSR") [1]_.

Conventions
-----------
Angles in degrees, ``theta_i`` the solar and ``theta_r`` the view zenith in [0, 90), ``phi`` the
relative azimuth in [0, 180]. brdfcorr's ``phi = 0`` is backscattering (sensor on the sun's side)
and ``phi = 180`` forward scattering. The kernel literature uses the same convention: the phase
angle is ``cos xi = cos ti cos tv + sin ti sin tv cos phi`` and the hot spot is at ``tv = ti,
phi = 0`` (Wanner et al. [2]_; P. Lewis' UCL kernel code states "hot spot direction is
vza == sza and raa = 0", and the AMBRALS code uses the same phase angle), so brdfcorr's ``phi`` is
passed unchanged.

Normalization: all four kernels are the MODIS forms [1]_, which vanish at ``ti = tv = 0``
(Ross-Thick and Ross-Thin by their constants -pi/4 and -pi/2; Li-Sparse-R and Li-Dense-R because
the overlap at nadir is O = 1 for any h/b and b/r). ``f_iso`` is therefore the BRDF at nadir
view and nadir sun.

Units: brdfcorr models return the BRDF in sr^-1. MODIS MCD43A1 kernel weights are reflectance
factors (BRF = pi BRDF) and must be divided by pi to be used as ``f_iso, f_vol, f_geo`` here. The
BRDF correction only uses ratios of the model, so the scale cancels there.

References
----------
.. [1] W. Lucht, C. B. Schaaf, A. H. Strahler (2000): An algorithm for the retrieval of albedo
   from space using semiempirical BRDF models. IEEE TGRS 38(2), 977-998; and A. H. Strahler,
   J.-P. Muller et al. (1999): MODIS BRDF/Albedo Product: Algorithm Theoretical Basis Document
   v5.0.
.. [2] W. Wanner, X. Li, A. H. Strahler (1995): On the derivation of kernels for kernel-driven
   models of bidirectional reflectance. JGR 100(D10), 21077-21089.
.. [3] J.-L. Roujean, M. Leroy, P.-Y. Deschamps (1992): A bidirectional reflectance model of the
   Earth's surface for the correction of remote sensing data. JGR 97(D18), 20455-20468.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from brdfcorr._arrays import TINY, array_function, cosd, sind
from brdfcorr.errors import ParameterError, UnknownNameError
from brdfcorr.geometry import ScatteringGeometry, _fill_doc
from brdfcorr.models._base import MAX_INTENSITY, Model, Parameter

__all__ = [
    "ross_thick",
    "ross_thin",
    "li_sparse",
    "li_dense",
    "kernel_driven",
    "VOLUME_KERNELS",
    "GEOMETRIC_KERNELS",
    "KERNEL_DRIVEN_MODELS",
    "LI_SPARSE_SHAPE",
    "LI_DENSE_SHAPE",
    "ROSS_THICK_LI_SPARSE",
    "ROSS_THIN_LI_SPARSE",
    "ROSS_THICK_LI_DENSE",
    "ROSS_THIN_LI_DENSE",
]

#: Crown shape (b/r) and relative height (h/b) of the MODIS Li-Sparse kernel: spheres whose centres
#: are two vertical radii above the ground [1]_ [2]_.
LI_SPARSE_SHAPE = {"b_r": 1.0, "h_b": 2.0}
#: The same for the MODIS Li-Dense kernel: vertically elongated (prolate) crowns, b/r = 2.5 [2]_
#: (also the "MODIS dense" parameters of the UCL/AMBRALS kernel code).
LI_DENSE_SHAPE = {"b_r": 2.5, "h_b": 2.0}

# Upper bounds keep the Li kernels finite on [0, 90) deg: (b/r) tan t <= 1e3 x 4e15 and its square
# stay far from overflow (b/r = 1e308 gives NaN); MODIS uses b/r = 1 or 2.5 and h/b = 2.
B_R = Parameter("b_r", "1", 1.0, 0.0, 1e3, lower_open=True, description="crown shape b/r of the Li kernels")
H_B = Parameter("h_b", "1", 2.0, 0.0, 1e3, lower_open=True, description="crown height h/b of the Li kernels")


class _Angles:
    """The trigonometry the kernels share at one geometry, each term computed once.

    Kept on its :class:`ScatteringGeometry` (:attr:`~ScatteringGeometry.shared`), so that several
    kernels, bands evaluated one by one with :meth:`Model.evaluate`, or RPV shapes at the same
    geometry reuse it.
    """

    def __init__(self, geometry: ScatteringGeometry):
        self.cos_i = geometry.cos_i
        self.cos_r = geometry.cos_r
        self.sin_i = sind(geometry.theta_i)
        self.sin_r = sind(geometry.theta_r)
        self.cos_phi = cosd(geometry.phi)
        self.sin_phi = sind(geometry.phi)
        self._phi = geometry.phi
        self._li: dict[tuple[float, float], tuple] = {}

    @cached_property
    def one_minus_cos_xi(self):
        """1 - cos(xi) = |i - v|^2 / 2, accurate near the hot spot (xi = 0)."""
        chord2 = (
            (self.sin_i - self.sin_r * self.cos_phi) ** 2
            + (self.sin_r * self.sin_phi) ** 2
            + (self.cos_i - self.cos_r) ** 2
        )
        return np.clip(0.5 * chord2, 0.0, 2.0)

    @cached_property
    def ross_phase(self):
        """(pi/2 - xi) cos xi + sin xi, the phase term of both Ross kernels [2]_."""
        half_chord = np.sqrt(0.5 * self.one_minus_cos_xi)  # sin(xi / 2), in [0, 1]
        xi = 2.0 * np.arcsin(half_chord)
        cos_xi = 1.0 - self.one_minus_cos_xi
        sin_xi = 2.0 * half_chord * np.sqrt(1.0 - half_chord**2)
        return (0.5 * math.pi - xi) * cos_xi + sin_xi

    @cached_property
    def tan_i(self):
        return self.sin_i / np.maximum(self.cos_i, TINY)

    @cached_property
    def tan_r(self):
        return self.sin_r / np.maximum(self.cos_r, TINY)

    @cached_property
    def one_minus_cos_phi(self):
        """1 - cos(phi) as 2 sin^2(phi / 2), without the cancellation of the subtraction near phi = 0
        (the hot spot): at phi = 1e-6 deg, 1 - cos(phi) rounds to 1.1e-16 instead of 1.5e-16."""
        return 2.0 * sind(0.5 * self._phi) ** 2

    def _primed(self, b_r: float):
        # Zeniths of the equivalent spheres: tan t' = (b/r) tan t [2]_, eqs. 37 and 52.
        if b_r == 1.0:
            return (
                self.tan_i, self.tan_r,
                1.0 / np.maximum(self.cos_i, TINY), 1.0 / np.maximum(self.cos_r, TINY),
                self.cos_i, self.cos_r, self.sin_i, self.sin_r,
            )
        tan_i, tan_r = b_r * self.tan_i, b_r * self.tan_r
        sec_i, sec_r = np.hypot(1.0, tan_i), np.hypot(1.0, tan_r)
        cos_i, cos_r = 1.0 / sec_i, 1.0 / sec_r
        return tan_i, tan_r, sec_i, sec_r, cos_i, cos_r, tan_i * cos_i, tan_r * cos_r

    def li_terms(self, b_r: float, h_b: float):
        """Overlap O, sec ti' + sec tv', (1 + cos xi') sec ti' sec tv' of the Li kernels [2]_."""
        key = (b_r, h_b)
        if key not in self._li:
            tan_i, tan_r, sec_i, sec_r, cos_i, cos_r, sin_i, sin_r = self._primed(b_r)
            both = sec_i + sec_r
            # D^2 = tan^2 ti' + tan^2 tv' - 2 tan ti' tan tv' cos phi, as a sum of non-negative terms.
            product = tan_i * tan_r
            distance2 = (tan_i - tan_r) ** 2 + 2.0 * product * self.one_minus_cos_phi
            cos_t = np.clip(h_b * np.sqrt(distance2 + (product * self.sin_phi) ** 2) / both, 0.0, 1.0)
            t = np.arccos(cos_t)
            overlap = (t - np.sqrt(1.0 - cos_t**2) * cos_t) * both / math.pi
            one_plus_cos_xi = 1.0 + cos_i * cos_r + sin_i * sin_r * self.cos_phi
            self._li[key] = (overlap, both, one_plus_cos_xi * sec_i * sec_r)
        return self._li[key]


def _angles(geometry: ScatteringGeometry) -> _Angles:
    """The kernels' trigonometry at ``geometry``, computed once and kept on it."""
    if "kernel_angles" not in geometry.shared:
        geometry.shared["kernel_angles"] = _Angles(geometry)
    return geometry.shared["kernel_angles"]


def _ross_thick(angles: _Angles):
    return angles.ross_phase / np.maximum(angles.cos_i + angles.cos_r, TINY) - 0.25 * math.pi


def _ross_thin(angles: _Angles):
    return angles.ross_phase / np.maximum(angles.cos_i * angles.cos_r, TINY) - 0.5 * math.pi


def _li_sparse(angles: _Angles, b_r=LI_SPARSE_SHAPE["b_r"], h_b=LI_SPARSE_SHAPE["h_b"]):
    overlap, both, cross = angles.li_terms(b_r, h_b)
    return overlap - both + 0.5 * cross


def _li_dense(angles: _Angles, b_r=LI_DENSE_SHAPE["b_r"], h_b=LI_DENSE_SHAPE["h_b"]):
    overlap, both, cross = angles.li_terms(b_r, h_b)
    # 0 <= O <= (sec ti' + sec tv') / 2, so the denominator is >= 1.
    return cross / (both - overlap) - 2.0


_KERNELS = {"ross_thick": _ross_thick, "ross_thin": _ross_thin, "li_sparse": _li_sparse, "li_dense": _li_dense}

#: Names of the volume-scattering kernels.
VOLUME_KERNELS: tuple[str, ...] = ("ross_thick", "ross_thin")
#: Names of the geometric-optical (shadowing) kernels.
GEOMETRIC_KERNELS: tuple[str, ...] = ("li_sparse", "li_dense")


def _kernel_at(geometry: ScatteringGeometry, name: str):
    """A registered kernel at a geometry, computed once per geometry (shared by all bands)."""
    if name not in geometry.shared:
        geometry.shared[name] = _KERNELS[name](_angles(geometry))
    return geometry.shared[name]


def _li_shape(function: str, b_r, h_b) -> tuple[float, float]:
    values = []
    for parameter, value in ((B_R, b_r), (H_B, h_b)):
        if np.ndim(value) != 0:
            raise ParameterError(f"{function}: {parameter.name} must be a scalar, got {value!r}")
        parameter.check(value, function)
        values.append(float(value))
    return values[0], values[1]


@array_function("K_vol", "1", "Ross-Thick volume-scattering kernel")
@_fill_doc
def ross_thick(theta_i, theta_r, phi):
    """Ross-Thick volume-scattering kernel (MODIS normalization).

    Parameters
    ----------
    %(zeniths)s
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 0 is backscattering (hot spot at ``theta_r =
        theta_i, phi = 0``), 180 forward scattering.

    Returns
    -------
    %(kernel_value)s

    Notes
    -----
    Roujean et al. (1992) [3]_ for a dense leaf canopy, in the form of Wanner et al. (1995) [2]_
    and the MODIS ATBD [1]_::

        K = ((pi/2 - xi) cos xi + sin xi) / (cos ti + cos tv) - pi/4
        cos xi = cos ti cos tv + sin ti sin tv cos phi

    At the hot spot (``tv = ti, phi = 0``, xi = 0) ``K = (pi/4)(sec ti - 1)``. For fixed zeniths it
    is largest at phi = 0. The phase term falls with xi up to xi = 90 deg and is symmetric about it,
    and xi grows with phi, so K falls monotonically from phi = 0 to phi = 180 only when
    ``ti + tv <= 90`` deg; otherwise it falls to its minimum where xi = 90 deg
    (``cos phi = -cot ti cot tv``) and rises from there to phi = 180: ``ross_thick(60, 60, 109.47)``
    = 0.2146 < ``ross_thick(60, 60, 180)`` = 0.3424. Along the principal plane it has no maximum at
    the hot spot but keeps rising towards grazing views (it has no hot-spot peak of its own).

    Examples
    --------
    >>> float(ross_thick(0.0, 0.0, 0.0))
    0.0
    >>> round(float(ross_thick(30.0, 30.0, 0.0)), 6)  # (pi/4)(sec 30 - 1)
    0.121502
    """
    return _kernel_at(ScatteringGeometry(theta_i, theta_r, phi), "ross_thick")


@array_function("K_vol", "1", "Ross-Thin volume-scattering kernel")
@_fill_doc
def ross_thin(theta_i, theta_r, phi):
    """Ross-Thin volume-scattering kernel (MODIS normalization).

    Parameters
    ----------
    %(angles_backscattering)s

    Returns
    -------
    %(kernel_value)s

    Notes
    -----
    The single-scattering approximation for a sparse (thin) leaf layer, Wanner et al. (1995) [2]_,
    MODIS ATBD [1]_::

        K = ((pi/2 - xi) cos xi + sin xi) / (cos ti cos tv) - pi/2

    At the hot spot ``K = (pi/2) tan^2 ti``.
    """
    return _kernel_at(ScatteringGeometry(theta_i, theta_r, phi), "ross_thin")


@array_function("K_geo", "1", "Li-Sparse-Reciprocal geometric-optical kernel")
@_fill_doc
def li_sparse(theta_i, theta_r, phi, *, b_r=LI_SPARSE_SHAPE["b_r"], h_b=LI_SPARSE_SHAPE["h_b"]):
    """Li-Sparse-Reciprocal geometric-optical kernel (MODIS normalization).

    Parameters
    ----------
    %(angles_backscattering)s
    b_r, h_b : float, keyword-only
        Crown shape (vertical / horizontal radius) and relative height of the crown centres
        (height / vertical radius), > 0. The defaults are MODIS's, b/r = 1 and h/b = 2 [1]_; the
        registered models use these.

    Returns
    -------
    %(kernel_value)s

    Notes
    -----
    Wanner et al. (1995) [2]_, eq. 32, made reciprocal as in Lucht et al. (2000) [1]_::

        K = O - sec ti' - sec tv' + (1 + cos xi') sec ti' sec tv' / 2
        O = (t - sin t cos t)(sec ti' + sec tv') / pi
        cos t = (h/b) sqrt(D^2 + (tan ti' tan tv' sin phi)^2) / (sec ti' + sec tv'),  in [0, 1]
        D^2 = tan^2 ti' + tan^2 tv' - 2 tan ti' tan tv' cos phi
        cos xi' = cos ti' cos tv' + sin ti' sin tv' cos phi
        tan t' = (b/r) tan t

    At the hot spot ``K = sec ti' (sec ti' - 1)``, a cusp (the slope along the principal plane jumps
    there); for fixed zeniths K falls monotonically from phi = 0 to phi = 180. Along the principal
    plane, with the MODIS shape (b/r = 1, h/b = 2):

    - the hot spot is a local maximum only for ti < 59.60 deg: on its far side (tv > ti, phi = 0)
      the slope ``dK/dtv = sec ti (sec ti tan ti - tan ti / 2 - (4/pi) sec ti)`` [per radian]
      turns positive where ``tan ti - sin ti / 2 = 4/pi``;
    - it is the maximum over the whole principal plane only for ti <= 36.87 deg (sin ti = 3/5).
      Beyond, K rises towards grazing backscatter views without bound: for h/b >= 1 the shadows
      stop overlapping as tv -> 90 deg at phi = 0 (O = 0), so
      ``K = sec tv' ((1 + cos(tv' - ti')) sec ti' / 2 - 1) - sec ti'``, and the factor of sec tv'
      tends to (1 + sin ti') / (2 cos ti') - 1, positive for sin ti' > 3/5. For example
      ``li_sparse(60, 75, 0)`` = 2.332 > ``li_sparse(60, 60, 0)`` = 2.000.

    Examples
    --------
    >>> float(li_sparse(0.0, 0.0, 0.0))
    0.0
    """
    b_r, h_b = _li_shape("li_sparse", b_r, h_b)
    return _li_sparse(_angles(ScatteringGeometry(theta_i, theta_r, phi)), b_r, h_b)


@array_function("K_geo", "1", "Li-Dense-Reciprocal geometric-optical kernel")
@_fill_doc
def li_dense(theta_i, theta_r, phi, *, b_r=LI_DENSE_SHAPE["b_r"], h_b=LI_DENSE_SHAPE["h_b"]):
    """Li-Dense-Reciprocal geometric-optical kernel (MODIS normalization).

    Parameters
    ----------
    %(angles_backscattering)s
    b_r, h_b : float, keyword-only
        Crown shape and relative height, > 0. The defaults are the MODIS Li-Dense values,
        b/r = 2.5 (prolate crowns) and h/b = 2 [2]_; the registered models use these.

    Returns
    -------
    %(kernel_value)s

    Notes
    -----
    Wanner et al. (1995) [2]_, eq. 47, has ``(1 + cos xi') sec tv'`` in the numerator, which is not
    reciprocal; the reciprocal form used with MODIS (as Li-Sparse-R, [1]_) multiplies it by
    ``sec ti'``::

        K = (1 + cos xi') sec ti' sec tv' / (sec ti' + sec tv' - O) - 2

    with O, xi' and the primed angles as in :func:`li_sparse`. At the hot spot
    ``K = 2 (sec ti' - 1)``.

    Examples
    --------
    >>> float(li_dense(0.0, 0.0, 0.0))
    0.0
    """
    b_r, h_b = _li_shape("li_dense", b_r, h_b)
    return _li_dense(_angles(ScatteringGeometry(theta_i, theta_r, phi)), b_r, h_b)


# --- Models ----------------------------------------------------------------------------------

# f_iso, f_vol, f_geo <= MAX_INTENSITY keep the model finite: the kernels are at most of the order
# of 1 / (cos ti cos tr) <= 1.6e31 on [0, 90) deg (see MAX_INTENSITY). MCD43A1 stores at most 32.766.
F_ISO = Parameter(
    "f_iso", "sr^-1", 0.03, 0.0, MAX_INTENSITY,
    description="isotropic weight: the BRDF at nadir sun and view (MODIS MCD43A1 f_iso / pi)",
)
F_VOL = Parameter(
    "f_vol", "sr^-1", 0.015, 0.0, MAX_INTENSITY,
    description="volume-scattering weight (MCD43A1 f_vol / pi); >= 0: a negative weight has no "
    "physical meaning and MCD43A1 stores none (valid range 0-32.766)",
)
F_GEO = Parameter(
    "f_geo", "sr^-1", 0.005, 0.0, MAX_INTENSITY,
    description="geometric-optical (shadowing) weight (MCD43A1 f_geo / pi); >= 0 as f_vol",
)
KERNEL_PARAMETERS = (F_ISO, F_VOL, F_GEO)

_TITLES = {
    "ross_thick": "Ross-Thick",
    "ross_thin": "Ross-Thin",
    "li_sparse": "Li-Sparse-Reciprocal",
    "li_dense": "Li-Dense-Reciprocal",
}


def _make_model(volume: str, geometric: str) -> Model:
    def basis(geometry: ScatteringGeometry):
        return 1.0, _kernel_at(geometry, volume), _kernel_at(geometry, geometric)

    def kernel(geometry: ScatteringGeometry, f_iso, f_vol, f_geo):
        _, k_vol, k_geo = basis(geometry)
        return f_iso + f_vol * k_vol + f_geo * k_geo

    name = f"{volume}_{geometric}"
    shape = LI_SPARSE_SHAPE if geometric == "li_sparse" else LI_DENSE_SHAPE
    return Model(
        name=name,
        description=(
            f"kernel-driven {_TITLES[volume]} {_TITLES[geometric]} model f_iso + f_vol K_vol + "
            f"f_geo K_geo (b/r = {shape['b_r']:g}, h/b = {shape['h_b']:g})"
            + ("; the MODIS MCD43 RTLSR model" if name == "ross_thick_li_sparse" else "")
        ),
        reference="Lucht, Schaaf & Strahler (2000), IEEE TGRS 38(2); Wanner, Li & Strahler (1995), JGR 100(D10)",
        parameters=KERNEL_PARAMETERS,
        kernel=kernel,
        linear=("f_iso", "f_vol", "f_geo"),
        basis=basis,
    )


ROSS_THICK_LI_SPARSE = _make_model("ross_thick", "li_sparse")
ROSS_THIN_LI_SPARSE = _make_model("ross_thin", "li_sparse")
ROSS_THICK_LI_DENSE = _make_model("ross_thick", "li_dense")
ROSS_THIN_LI_DENSE = _make_model("ross_thin", "li_dense")

#: The kernel-driven models by (volume kernel, geometric kernel).
KERNEL_DRIVEN_MODELS: dict[tuple[str, str], Model] = {
    (volume, geometric): model
    for model, volume, geometric in (
        (ROSS_THICK_LI_SPARSE, "ross_thick", "li_sparse"),
        (ROSS_THIN_LI_SPARSE, "ross_thin", "li_sparse"),
        (ROSS_THICK_LI_DENSE, "ross_thick", "li_dense"),
        (ROSS_THIN_LI_DENSE, "ross_thin", "li_dense"),
    )
}


@_fill_doc
def kernel_driven(theta_i, theta_r, phi, f_iso, f_vol, f_geo, volume="ross_thick", geometric="li_sparse"):
    """Kernel-driven (Ross-Li) BRDF ``f_iso + f_vol K_vol + f_geo K_geo``.

    Parameters
    ----------
    %(zeniths)s
    phi : array-like
        Relative azimuth [deg], in [0, 180]; 0 is backscattering (the hot spot is at
        ``theta_r = theta_i, phi = 0``, as in the kernel literature), 180 forward scattering.
    f_iso : array-like
        Isotropic weight [sr^-1], >= 0: the BRDF at nadir sun and nadir view.
    f_vol : array-like
        Weight of the volume-scattering kernel [sr^-1], >= 0.
    f_geo : array-like
        Weight of the geometric-optical kernel [sr^-1], >= 0.
    volume : {"ross_thick", "ross_thin"}
        The volume-scattering kernel (:data:`VOLUME_KERNELS`).
    geometric : {"li_sparse", "li_dense"}
        The geometric-optical kernel (:data:`GEOMETRIC_KERNELS`), both in their reciprocal forms.

    Returns
    -------
    %(brdf)s

    Raises
    ------
    brdfcorr.errors.UnknownNameError
        For a kernel name not in :data:`VOLUME_KERNELS` or :data:`GEOMETRIC_KERNELS`.
    brdfcorr.errors.ParameterError
        For NaN, infinite or negative weights.

    Notes
    -----
    The default is the MODIS RTLSR model (registry name ``ross_thick_li_sparse``) [1]_; the other
    combinations are registered as ``ross_thin_li_sparse``, ``ross_thick_li_dense`` and
    ``ross_thin_li_dense``. MODIS MCD43A1 weights are reflectance factors: divide them by pi
    (for a ratio, such as the BRDF correction factor, the scale does not matter). Weights of
    several bands (an xarray dimension ``band``) share the kernels, which are computed once.

    Examples
    --------
    At nadir sun and view every kernel is 0, so the BRDF is f_iso:

    >>> float(kernel_driven(0.0, 0.0, 0.0, f_iso=0.1, f_vol=0.05, f_geo=0.01))
    0.1
    """
    for kind, name, known in (("volume", volume, VOLUME_KERNELS), ("geometric", geometric, GEOMETRIC_KERNELS)):
        if name not in known:
            raise UnknownNameError(
                f"unknown {kind} kernel {name!r}; known {kind} kernels: {', '.join(known)}"
            )
    model = KERNEL_DRIVEN_MODELS[(volume, geometric)]
    return model(theta_i, theta_r, phi, f_iso=f_iso, f_vol=f_vol, f_geo=f_geo)
