"""Kernel-driven (Ross-Li) and RPV models: closed forms, published values, an independent scalar
implementation, properties over the domain, array kinds, invalid input."""

import importlib
import math
import warnings
from decimal import Decimal, getcontext, localcontext

import numpy as np
import pytest
import xarray as xr
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import brentq

from brdfcorr.errors import ParameterError, UnknownNameError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import (
    GEOMETRIC_KERNELS,
    REGISTRY,
    SURFACE_MODELS,
    VOLUME_KERNELS,
    get_model,
    kernel_driven,
    li_dense,
    li_sparse,
    ross_thick,
    ross_thin,
    rpv,
)
from brdfcorr.models._base import MAX_INTENSITY

KERNELS = {"ross_thick": ross_thick, "ross_thin": ross_thin, "li_sparse": li_sparse, "li_dense": li_dense}
MODEL_NAMES = ["ross_thick_li_sparse", "ross_thin_li_sparse", "ross_thick_li_dense", "ross_thin_li_dense"]
LI_SHAPE = {"li_sparse": (1.0, 2.0), "li_dense": (2.5, 2.0)}  # (b/r, h/b), MODIS
zenith = st.floats(0.0, 89.9)
azimuth = st.floats(0.0, 180.0)
sec = lambda degrees: 1.0 / math.cos(math.radians(degrees))  # noqa: E731


# --- Independent scalar implementation (vectors, plain math) ---------------------------------


def _direction(zenith_deg, azimuth_deg):
    """Unit vector at a zenith and azimuth; the sun is at azimuth 0, so phi = 0 is backscatter."""
    t, p = math.radians(zenith_deg), math.radians(azimuth_deg)
    return (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _ross_reference(ti, tv, phi, thick):
    xi = math.acos(max(-1.0, min(1.0, _dot(_direction(ti, 0.0), _direction(tv, phi)))))
    phase = (math.pi / 2 - xi) * math.cos(xi) + math.sin(xi)
    if thick:
        return phase / (math.cos(math.radians(ti)) + math.cos(math.radians(tv))) - math.pi / 4
    return phase / (math.cos(math.radians(ti)) * math.cos(math.radians(tv))) - math.pi / 2


def _li_reference(ti, tv, phi, dense, b_r, h_b):
    # Equivalent spheres: zeniths with tan t' = (b/r) tan t; the crown-centre shadows on the
    # ground lie at tan t' times the horizontal unit vectors of the sun and the view.
    ti_p = math.degrees(math.atan(b_r * math.tan(math.radians(ti))))
    tv_p = math.degrees(math.atan(b_r * math.tan(math.radians(tv))))
    sun_shadow = (math.tan(math.radians(ti_p)), 0.0)
    view_shadow = (math.tan(math.radians(tv_p)) * math.cos(math.radians(phi)),
                   math.tan(math.radians(tv_p)) * math.sin(math.radians(phi)))
    distance2 = (sun_shadow[0] - view_shadow[0]) ** 2 + (sun_shadow[1] - view_shadow[1]) ** 2
    cross = sun_shadow[0] * view_shadow[1] - sun_shadow[1] * view_shadow[0]  # tan ti' tan tv' sin phi
    sec_sum = sec(ti_p) + sec(tv_p)
    cos_t = min(1.0, h_b * math.sqrt(distance2 + cross**2) / sec_sum)
    t = math.acos(cos_t)
    overlap = (t - math.sin(t) * math.cos(t)) * sec_sum / math.pi
    cos_xi_p = _dot(_direction(ti_p, 0.0), _direction(tv_p, phi))
    if dense:
        return (1 + cos_xi_p) * sec(ti_p) * sec(tv_p) / (sec_sum - overlap) - 2
    return overlap - sec_sum + 0.5 * (1 + cos_xi_p) * sec(ti_p) * sec(tv_p)


def _reference(name, ti, tv, phi):
    if name.startswith("ross"):
        return _ross_reference(ti, tv, phi, thick=name == "ross_thick")
    return _li_reference(ti, tv, phi, name == "li_dense", *LI_SHAPE[name])


HAND_GEOMETRIES = [(30, 30, 0), (45, 20, 90), (60, 40, 180), (0, 0, 0), (10, 70, 135), (75, 75, 30),
                   (50, 5, 10), (20, 60, 170), (85, 80, 180)]


@pytest.mark.parametrize("name", list(KERNELS))
@pytest.mark.parametrize(("ti", "tv", "phi"), HAND_GEOMETRIES)
def test_kernels_equal_an_independent_scalar_implementation(name, ti, tv, phi):
    assert KERNELS[name](ti, tv, phi) == pytest.approx(_reference(name, ti, tv, phi), rel=1e-12, abs=1e-12)


def test_hand_table_at_three_geometries():
    # Step by step at (30, 30, 0): the hot spot, xi = 0, D = 0, so cos t = 0, t = pi/2, O = sec ti.
    assert ross_thick(30, 30, 0) == pytest.approx((math.pi / 2) / (2 * math.cos(math.radians(30))) - math.pi / 4)
    assert li_sparse(30, 30, 0) == pytest.approx(sec(30) - 2 * sec(30) + sec(30) ** 2)
    # (45, 20, 90): cos xi = cos 45 cos 20 (cross-principal plane).
    xi = math.acos(math.cos(math.radians(45)) * math.cos(math.radians(20)))
    expected = ((math.pi / 2 - xi) * math.cos(xi) + math.sin(xi)) / (
        math.cos(math.radians(45)) + math.cos(math.radians(20))) - math.pi / 4
    assert ross_thick(45, 20, 90) == pytest.approx(expected, rel=1e-12)
    # (60, 40, 180): forward principal plane, xi = 100 deg; D = tan 60 + tan 40, sin phi = 0.
    xi = math.radians(100)
    phase = (math.pi / 2 - xi) * math.cos(xi) + math.sin(xi)
    assert ross_thin(60, 40, 180) == pytest.approx(phase / (0.5 * math.cos(math.radians(40))) - math.pi / 2)
    distance = math.tan(math.radians(60)) + math.tan(math.radians(40))
    cos_t = min(1.0, 2 * distance / (sec(60) + sec(40)))
    assert cos_t == 1.0  # no overlap of the shadows: O = 0
    assert li_sparse(60, 40, 180) == pytest.approx(-(sec(60) + sec(40)) + 0.5 * (1 + math.cos(xi)) * sec(60) * sec(40))


# --- Closed forms: nadir, hot spot, azimuth independence -------------------------------------


@pytest.mark.parametrize("name", list(KERNELS))
def test_every_kernel_vanishes_at_nadir_sun_and_view(name):
    # MODIS normalization: Ross-Thick ((pi/2)/2 - pi/4) and Li-Sparse-R (O = 1, 1 - 2 + 1) vanish
    # at ti = tv = 0, and so do Ross-Thin ((pi/2)/1 - pi/2) and Li-Dense-R (2 / (2 - 1) - 2).
    for phi in (0.0, 90.0, 180.0):
        assert KERNELS[name](0.0, 0.0, phi) == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize("theta", [5.0, 30.0, 45.0, 70.0])
def test_hot_spot_closed_forms(theta):
    # At tv = ti, phi = 0: xi = 0, D = 0, t = pi/2, O = (sec ti' + sec tv') / 2.
    tan_p = 2.5 * math.tan(math.radians(theta))
    sec_dense = math.sqrt(1 + tan_p**2)
    assert ross_thick(theta, theta, 0) == pytest.approx(math.pi / 4 * (sec(theta) - 1), rel=1e-12)
    assert ross_thin(theta, theta, 0) == pytest.approx(math.pi / 2 * math.tan(math.radians(theta)) ** 2, rel=1e-12)
    assert li_sparse(theta, theta, 0) == pytest.approx(sec(theta) * (sec(theta) - 1), rel=1e-12)
    assert li_dense(theta, theta, 0) == pytest.approx(2 * (sec_dense - 1), rel=1e-12)


@pytest.mark.parametrize("name", list(KERNELS))
def test_kernels_do_not_depend_on_azimuth_for_a_nadir_sun(name):
    tv = np.linspace(0, 85, 18)[:, None]
    values = KERNELS[name](0.0, tv, np.linspace(0, 180, 7))
    np.testing.assert_allclose(values, np.broadcast_to(values[:, :1], values.shape), rtol=0, atol=1e-12)
    # Ross-Thick at a nadir sun: xi = tv.
    if name == "ross_thick":
        t = np.radians(tv[:, 0])
        expected = ((np.pi / 2 - t) * np.cos(t) + np.sin(t)) / (1 + np.cos(t)) - np.pi / 4
        np.testing.assert_allclose(values[:, 0], expected, rtol=1e-12, atol=1e-15)


def _white_sky_integral(kernel, nodes=64):
    # Bi-hemispherical integral 2 int BSA(mu_i) mu_i dmu_i, BSA(mu_i) = (1/pi) int K mu_v dmu_v dphi,
    # by Gauss-Legendre in cos(ti), cos(tv) and phi (K is symmetric in phi about 0).
    x, w = np.polynomial.legendre.leggauss(nodes)
    mu, w_mu = 0.5 * (x + 1), 0.5 * w
    phi, w_phi = 90.0 * (x + 1), 90.0 * w * np.pi / 180.0
    theta = np.degrees(np.arccos(mu))
    values = kernel(theta[:, None, None], theta[None, :, None], phi[None, None, :])
    bsa = 2.0 / np.pi * np.einsum("ijk,j,j,k->i", values, mu, w_mu, w_phi)
    return 2.0 * np.sum(bsa * mu * w_mu)


def test_white_sky_integrals_lucht_2000_table_1():
    # Lucht, Schaaf & Strahler (2000), Table 1: bi-hemispherical integrals of the kernels,
    # RossThick 0.189184 and LiSparse(-R) -1.377622 (the isotropic kernel integrates to 1).
    assert _white_sky_integral(ross_thick) == pytest.approx(0.189184, abs=1e-5)
    assert _white_sky_integral(li_sparse) == pytest.approx(-1.377622, abs=1e-4)


# --- Reciprocity and the position of the hot spot --------------------------------------------


@given(zenith, zenith, azimuth)
def test_kernels_and_rpv_are_reciprocal(ti, tv, phi):
    for name, kernel in KERNELS.items():
        value = kernel(ti, tv, phi)
        assert value == pytest.approx(kernel(tv, ti, phi), rel=1e-9, abs=1e-9), name
    params = dict(rho0=0.05, k=0.7, theta=-0.2, rho_c=0.3)
    assert rpv(ti, tv, phi, **params) == pytest.approx(rpv(tv, ti, phi, **params), rel=1e-9)


@pytest.mark.parametrize("name", list(KERNELS))
def test_backscatter_is_the_brightest_azimuth(name):
    # For any pair of zeniths every kernel is largest at phi = 0 (the hot-spot side). The Ross
    # phase term (pi/2 - xi) cos xi + sin xi is symmetric about xi = 90 deg with its minimum
    # there, and |tv - ti| is at least as far from 90 deg as ti + tv; the Li kernels fall
    # monotonically with phi.
    theta = np.arange(0.0, 89.6, 2.5)
    ti, tv, phi = np.meshgrid(theta, theta, np.arange(0.0, 180.01, 0.5), indexing="ij")
    values = KERNELS[name](ti, tv, phi)
    assert np.all(values[..., :1] >= values - 1e-12 * (1.0 + np.abs(values)))
    if name.startswith("li"):
        assert np.all(np.diff(values, axis=-1) <= 1e-12)


def _principal_plane(function, theta_i=30.0, step=0.1):
    # Signed view zenith: > 0 on the sun's side (phi = 0), < 0 on the forward side (phi = 180).
    signed = np.arange(-89.0, 89.0 + step / 2, step)
    return signed, function(theta_i, np.abs(signed), np.where(signed >= 0, 0.0, 180.0))


def test_li_sparse_peaks_at_the_hot_spot_in_the_principal_plane():
    signed, values = _principal_plane(li_sparse)
    assert signed[np.argmax(values)] == pytest.approx(30.0)
    # A cusp: it falls on both sides (Li-Dense-R likewise).
    signed, values = _principal_plane(li_dense)
    assert signed[np.argmax(values)] == pytest.approx(30.0)


def test_ross_thick_has_no_hot_spot_peak_of_its_own():
    # Ross-Thick is largest in the backscatter direction for each view zenith, and so brighter at
    # the hot spot than in the specular direction; but along the principal plane it keeps rising
    # past the hot spot towards grazing views (its derivative at the hot spot is
    # (pi/8) sin ti / cos^2 ti > 0 per radian, as f'(0) = 0): the hot-spot peak of RTLSR comes from Li-Sparse.
    assert ross_thick(30, 30, 0) > ross_thick(30, 30, 180)
    signed, values = _principal_plane(ross_thick)
    assert signed[np.argmax(values)] == pytest.approx(89.0)
    slope = (ross_thick(30, 30.001, 0) - ross_thick(30, 29.999, 0)) / math.radians(0.002)
    assert slope == pytest.approx(math.pi / 8 * 0.5 / 0.75, rel=1e-5)


def _decimal_pi():
    # The pi() recipe of the Python documentation of the decimal module ("Recipes").
    getcontext().prec += 2
    three = Decimal(3)
    lasts, t, s, n, na, d, da_ = 0, three, 3, 1, 0, 0, 24
    while s != lasts:
        lasts = s
        n, na = n + na, na + 8
        d, da_ = d + da_, da_ + 32
        t = (t * n) / d
        s += t
    getcontext().prec -= 2
    return +s


def _decimal_series(x, first, power):
    # sin (first = x, power = 1) and cos (first = 1, power = 0) by their Taylor series, as the
    # sin() and cos() recipes of the decimal documentation.
    getcontext().prec += 2
    total, term, k, last = first, first, power, None
    while total != last:
        last = total
        term = -term * x * x / ((k + 1) * (k + 2))
        k += 2
        total += term
    getcontext().prec -= 2
    return +total


def _decimal_asin(x):
    # asin x = sum (2n)! / (4^n (n!)^2 (2n + 1)) x^(2n + 1) after halving the angle down to
    # |x| <= 1/2 (sin(a/2) = x / sqrt(2 (1 + sqrt(1 - x^2))) for x = sin a, 0 <= a <= pi/2).
    if x > Decimal("0.5"):
        return 2 * _decimal_asin(x / (2 * (1 + (1 - x * x).sqrt())).sqrt())
    total, power, coefficient, n, last = x, x, Decimal(1), 0, None
    while total != last:
        last = total
        n += 1
        power *= x * x
        coefficient *= Decimal(2 * n - 1) / (2 * n)
        total += coefficient * power / (2 * n + 1)
    return total


def _li_sparse_equal_zeniths_decimal(theta_deg, phi_deg):
    """Li-Sparse-R (b/r = 1, h/b = 2) at ti = tv = theta in 40-digit decimal arithmetic, from the
    closed form of the kernel at equal zeniths, written without 1 - cos phi:

        D^2 = 2 tan^2 theta (1 - cos phi) = 4 tan^2 theta sin^2(phi/2),   tan ti tan tv sin phi = tan^2 theta sin phi
        cos t = min(1, 2 sqrt(D^2 + tan^4 theta sin^2 phi) / (2 sec theta)),  O = (t - sin t cos t) 2 sec theta / pi
        (1 + cos xi') sec^2 theta / 2 = (2 - 2 sin^2 theta sin^2(phi/2)) sec^2 theta / 2 = sec^2 theta - tan^2 theta sin^2(phi/2)
        K = O - 2 sec theta + sec^2 theta - tan^2 theta sin^2(phi/2)
    """
    with localcontext() as context:
        context.prec = 40
        pi = _decimal_pi()
        theta, phi = Decimal(theta_deg) * pi / 180, Decimal(phi_deg) * pi / 180
        sin_t, cos_t = _decimal_series(theta, theta, 1), _decimal_series(theta, Decimal(1), 0)
        tan, secant = sin_t / cos_t, 1 / cos_t
        half = _decimal_series(phi / 2, phi / 2, 1) ** 2  # sin^2(phi / 2)
        sin_phi = _decimal_series(phi, phi, 1)
        cos_shadow = min(Decimal(1), 2 * (4 * tan**2 * half + tan**4 * sin_phi**2).sqrt() / (2 * secant))
        t = pi / 2 - _decimal_asin(cos_shadow)
        overlap = (t - (1 - cos_shadow**2).sqrt() * cos_shadow) * 2 * secant / pi
        return overlap - 2 * secant + secant**2 - tan**2 * half


@pytest.mark.parametrize("theta", [5.0, 10.0, 30.0, 45.0, 60.0, 75.0])
def test_li_sparse_next_to_the_hot_spot_equals_a_40_digit_evaluation(theta):
    # At phi = 1e-6 deg, 1 - cos phi = 1.5e-16 is below the spacing of doubles near 1: formed by
    # subtraction it rounded to 1.1e-16 and Li-Sparse came out 7.4e-8 (theta = 5) to 2.6e-10
    # (theta = 75) too high. brdfcorr forms it as 2 sin^2(phi/2); the reference is the closed form
    # above in decimal arithmetic (Python's decimal module, 40 digits; pi, sin and cos after the
    # recipes of its documentation). The reference itself equals the kernel at phi = 0 (the closed
    # form sec(sec - 1)) and at phi = 20 deg, where doubles lose nothing.
    for phi in ("0", "20"):
        reference = float(_li_sparse_equal_zeniths_decimal(str(theta), phi))
        assert li_sparse(theta, theta, float(phi)) == pytest.approx(reference, rel=1e-13)
    assert float(_li_sparse_equal_zeniths_decimal(str(theta), "0")) == pytest.approx(sec(theta) * (sec(theta) - 1), rel=1e-13)
    reference = _li_sparse_equal_zeniths_decimal(str(theta), "1e-6")
    assert li_sparse(theta, theta, 1e-6) == pytest.approx(float(reference), rel=1e-12)


def test_ross_thick_falls_with_phi_only_while_the_phase_angle_is_below_90_deg():
    # The phase term (pi/2 - xi) cos xi + sin xi has the derivative -(pi/2 - xi) sin xi: it falls up
    # to xi = 90 deg and rises after, and xi grows with phi from |ti - tv| to ti + tv. So for
    # ti + tv <= 90 deg Ross-Thick falls monotonically over phi in [0, 180]; otherwise it is least
    # where cos phi = -cot ti cot tv (xi = 90 deg) and rises from there to phi = 180.
    phi = np.arange(0.0, 180.01, 0.25)
    for ti in np.arange(0.0, 89.6, 2.5):
        for tv in np.arange(0.0, 89.6, 2.5):
            values = ross_thick(ti, tv, phi)
            steps = np.diff(values)
            tol = 1e-12 * (1.0 + np.abs(values[1:]))
            if ti + tv <= 90.0:
                assert np.all(steps <= tol), (ti, tv)
                continue
            least = math.degrees(math.acos(-1.0 / (math.tan(math.radians(ti)) * math.tan(math.radians(tv)))))
            assert abs(phi[np.argmin(values)] - least) <= 0.25, (ti, tv)
            falling, rising = phi[1:] <= least, phi[:-1] >= least
            assert np.all(steps[falling] <= tol[falling]) and np.all(steps[rising] >= -tol[rising]), (ti, tv)
    # The docstring's example: (60, 60), least at phi = acos(-1/3) = 109.47 deg.
    assert math.degrees(math.acos(-1 / 3)) == pytest.approx(109.47, abs=0.005)
    assert ross_thick(60, 60, 109.47) == pytest.approx(0.2146, abs=5e-5)
    assert ross_thick(60, 60, 109) == pytest.approx(0.2146, abs=5e-5)
    assert ross_thick(60, 60, 180) == pytest.approx(0.3424, abs=5e-5)
    assert ross_thick(60, 60, 0) > ross_thick(60, 60, 180)  # still largest at phi = 0


def test_li_sparse_hot_spot_is_the_principal_plane_maximum_only_up_to_36_87_deg():
    # Near the hot spot on its far side (tv = ti + d, phi = 0, MODIS shape) cos t = sec ti d, so
    # O = sec ti + sec ti tan ti d / 2 - (4/pi) sec^2 ti d and the slope is
    # dK/dtv = sec ti (sec ti tan ti - tan ti / 2 - (4/pi) sec ti): positive from
    # tan ti - sin ti / 2 = 4/pi, ti = 59.60 deg, where the hot spot stops being a local maximum.
    local = brentq(lambda t: math.tan(t) - math.sin(t) / 2 - 4 / math.pi, 0.5, 1.4, xtol=1e-15)
    assert math.degrees(local) == pytest.approx(59.60, abs=0.005)
    for ti in (30.0, 45.0, 59.0, 60.0, 70.0):
        t = math.radians(ti)
        slope = sec(ti) * (sec(ti) * math.tan(t) - math.tan(t) / 2 - 4 / math.pi * sec(ti))
        numeric = (li_sparse(ti, ti + 1e-6, 0.0) - li_sparse(ti, ti, 0.0)) / math.radians(1e-6)
        assert numeric == pytest.approx(slope, rel=1e-4, abs=1e-6)
        assert (slope > 0) == (ti > math.degrees(local))
    # At phi = 0 and tv -> 90 deg the shadows no longer overlap (O = 0) and
    # K = sec tv ((1 + cos(tv - ti)) sec ti / 2 - 1) - sec ti: the factor of sec tv tends to
    # (1 + sin ti) / (2 cos ti) - 1, positive (K unbounded) for sin ti > 3/5, ti > 36.87 deg.
    threshold = math.degrees(math.asin(0.6))
    assert threshold == pytest.approx(36.87, abs=0.005)
    for ti in (60.0, 45.0, 37.0):
        factor = (1 + math.sin(math.radians(ti))) / (2 * math.cos(math.radians(ti))) - 1
        tv = 89.9999
        assert li_sparse(ti, tv, 0.0) == pytest.approx(sec(tv) * ((1 + math.cos(math.radians(tv - ti))) * sec(ti) / 2 - 1)
                                                      - sec(ti), rel=1e-9)
        assert li_sparse(ti, tv, 0.0) * math.cos(math.radians(tv)) == pytest.approx(factor, abs=1e-5)
    signed = np.concatenate([-89.9999 + np.zeros(1), np.arange(-89.9, 89.95, 0.1), 89.9999 + np.zeros(1)])
    for ti in (5.0, 20.0, 30.0, 36.8, 36.86, 36.88, 37.0, 40.0, 45.0, 60.0):
        plane = np.append(signed, ti)  # the hot spot itself
        values = li_sparse(ti, np.abs(plane), np.where(plane >= 0, 0.0, 180.0))
        hot = li_sparse(ti, ti, 0.0)
        if ti < threshold:
            assert values.max() <= hot + 1e-12 * abs(hot), ti
        else:
            assert values.max() > hot and plane[np.argmax(values)] == pytest.approx(89.9999), ti
        # A local maximum below 59.60 deg; above, K rises from the hot spot towards larger tv.
        assert li_sparse(ti, ti - 0.01, 0.0) < hot and li_sparse(ti, ti, 0.01) < hot
        assert (li_sparse(ti, ti + 0.01, 0.0) < hot) == (ti < math.degrees(local))
    # The docstring's example.
    assert li_sparse(60, 75, 0) == pytest.approx(2.332, abs=5e-4)
    assert li_sparse(60, 60, 0) == pytest.approx(2.000, abs=5e-4)
    assert li_sparse(60, 75, 0) > li_sparse(60, 60, 0)


def test_rtlsr_peaks_at_the_hot_spot_over_the_view_hemisphere():
    # For ti = 30 and positive weights the full model, on a fine (theta_r, phi) grid, is largest
    # at theta_r = 30, phi = 0 (never on the forward side). This holds while f_vol / f_geo is below
    # the ratio of the one-sided slopes of Li-Sparse-R and Ross-Thick at the hot spot (~4.8 at
    # ti = 30; beyond it the Ross-Thick rise moves the maximum to larger backscatter view zeniths).
    theta_r, phi = np.meshgrid(np.arange(0.0, 89.01, 0.1), np.arange(0.0, 180.01, 0.5), indexing="ij")
    for f_vol, f_geo in [(0.05, 0.025), (0.02, 0.02), (0.0, 0.01), (0.09, 0.02)]:
        values = kernel_driven(30.0, theta_r, phi, f_iso=0.1, f_vol=f_vol, f_geo=f_geo)
        best = np.unravel_index(np.argmax(values), values.shape)
        assert (theta_r[best], phi[best]) == pytest.approx((30.0, 0.0))
    slopes = [
        (kernel(30, 30.001, 0) - kernel(30, 30, 0)) / 0.001 for kernel in (ross_thick, li_sparse)
    ]
    threshold = -slopes[1] / slopes[0]
    assert 4.5 < threshold < 5.0
    values = kernel_driven(30.0, theta_r, phi, f_iso=0.1, f_vol=0.1, f_geo=0.01)  # f_vol/f_geo = 10
    best = np.unravel_index(np.argmax(values), values.shape)
    assert theta_r[best] > 30.0 and phi[best] == 0.0


# --- The models and the registry --------------------------------------------------------------


@pytest.mark.parametrize("name", MODEL_NAMES)
def test_kernel_driven_model_is_the_weighted_sum_of_its_kernels(name):
    volume, geometric = name.rsplit("_", 2)[0], "_".join(name.rsplit("_", 2)[1:])
    assert volume in VOLUME_KERNELS and geometric in GEOMETRIC_KERNELS
    rng = np.random.default_rng(5)
    ti, tv, phi = rng.uniform(0, 85, 200), rng.uniform(0, 85, 200), rng.uniform(0, 180, 200)
    expected = 0.1 + 0.04 * KERNELS[volume](ti, tv, phi) + 0.02 * KERNELS[geometric](ti, tv, phi)
    result = kernel_driven(ti, tv, phi, 0.1, 0.04, 0.02, volume=volume, geometric=geometric)
    np.testing.assert_allclose(result, expected, rtol=1e-12)
    model = get_model(name)
    np.testing.assert_array_equal(model(ti, tv, phi, f_iso=0.1, f_vol=0.04, f_geo=0.02), result)
    assert model.linear == ("f_iso", "f_vol", "f_geo") and model.shape_names == ()
    assert name in REGISTRY and name in SURFACE_MODELS
    for parameter in model.parameters:
        # Bounded above (MAX_INTENSITY = 1e3 sr^-1; a white Lambertian surface is 0.32) so that every
        # factor stays finite over the angle domain.
        assert parameter.units == "sr^-1" and parameter.lower == 0.0 and parameter.upper == MAX_INTENSITY


def test_default_is_modis_rtlsr_and_modis_weights_are_divided_by_pi():
    # MCD43A1 weights are reflectance factors: BRF = pi BRDF.
    weights = np.array([0.25, 0.12, 0.03])
    brf = math.pi * kernel_driven(40, 10, 120, *(weights / math.pi))
    assert brf == pytest.approx(weights @ [1.0, ross_thick(40, 10, 120), li_sparse(40, 10, 120)], rel=1e-12)
    assert kernel_driven(0, 0, 0, 0.2, 0.1, 0.05) == pytest.approx(0.2)


def test_terms_are_computed_once_per_geometry_and_shared():
    geometry = ScatteringGeometry(np.full(5, 40.0), np.linspace(0, 60, 5), np.linspace(0, 180, 5))
    model = get_model("ross_thick_li_sparse")
    first, second = model.terms(geometry, {}), model.terms(geometry, {})
    assert first[0] == 1.0
    assert first[1] is second[1] and first[2] is second[2]
    # The other models at the same geometry reuse the same kernel arrays.
    assert get_model("ross_thick_li_dense").terms(geometry, {})[1] is first[1]
    np.testing.assert_array_equal(
        model.evaluate(geometry, f_iso=0.1, f_vol=0.02, f_geo=0.01),
        kernel_driven(geometry.theta_i, geometry.theta_r, geometry.phi, 0.1, 0.02, 0.01),
    )


@pytest.mark.parametrize(("volume", "geometric", "message"), [
    ("ross_medium", "li_sparse", "unknown volume kernel 'ross_medium'; known volume kernels: ross_thick, ross_thin"),
    ("ross_thick", "roujean", "unknown geometric kernel 'roujean'; known geometric kernels: li_sparse, li_dense"),
])
def test_unknown_kernel_names(volume, geometric, message):
    with pytest.raises(UnknownNameError, match=message) as raised:
        kernel_driven(30, 30, 0, 0.1, 0.0, 0.0, volume=volume, geometric=geometric)
    assert isinstance(raised.value, KeyError) and str(raised.value) == message


@pytest.mark.parametrize(("call", "name"), [
    (lambda: kernel_driven(30, 30, 0, -0.01, 0.0, 0.0), "f_iso"),
    (lambda: kernel_driven(30, 30, 0, 0.1, -0.01, 0.0), "f_vol"),
    (lambda: kernel_driven(30, 30, 0, 0.1, 0.0, np.nan), "f_geo"),
    (lambda: rpv(30, 30, 0, rho0=-1.0, k=1.0, theta=0.0, rho_c=1.0), "rho0"),
    (lambda: rpv(30, 30, 0, rho0=0.1, k=0.0, theta=0.0, rho_c=1.0), "k"),
    (lambda: rpv(30, 30, 0, rho0=0.1, k=2.5, theta=0.0, rho_c=1.0), "k"),
    (lambda: rpv(30, 30, 0, rho0=0.1, k=1.0, theta=-1.2, rho_c=1.0), "theta"),
    (lambda: rpv(30, 30, 0, rho0=0.1, k=1.0, theta=0.0, rho_c=1.5), "rho_c"),
    (lambda: li_sparse(30, 30, 0, b_r=0.0), "b_r"),
    (lambda: li_dense(30, 30, 0, h_b=-2.0), "h_b"),
])
def test_invalid_parameters_raise_naming_them(call, name):
    with pytest.raises(ParameterError, match=rf"parameter {name} = .* is invalid"):
        call()


def test_li_shape_can_be_changed():
    # b/r and h/b enter as in the independent implementation; b/r = 1 for Li-Dense is the
    # variant some codes use.
    for b_r, h_b in [(1.0, 2.0), (2.0, 1.5), (0.5, 3.0)]:
        assert li_dense(45, 20, 60, b_r=b_r, h_b=h_b) == pytest.approx(
            _li_reference(45, 20, 60, True, b_r, h_b), rel=1e-12)
        assert li_sparse(45, 20, 60, b_r=b_r, h_b=h_b) == pytest.approx(
            _li_reference(45, 20, 60, False, b_r, h_b), rel=1e-12)


# --- RPV -------------------------------------------------------------------------------------


# RAMI-IV anisotropic backgrounds (JRC, rami-benchmark.jrc.ec.europa.eu, RAMI-IV/EXPERIMENTS4/
# ABSTRACT_CANOPIES/HETEROGENEOUS/ANISOTROPIC_BACKGROUND/MISCELLANEOUS/rpv_<rho>_<k>_<theta>_SZA<sza>.dat):
# BRF tables of the RPV model with a separate hot-spot parameter rho_HS, given to 4 decimals, at
# view zeniths 0-75 (rows) and relative azimuths 0, 30, ..., 180 (columns). RAMI's azimuth 180 is
# the backscatter side (its maxima with theta_HG < 0 are there), i.e. brdfcorr's phi = 180 - phi_RAMI.
RAMI_RPV = {
    # (rho, k, theta_HG, rho_HS, sza): {view zenith: BRF at phi_RAMI = 0, 30, ..., 180}
    (0.05, 0.95, -0.10, 0.05, 50.0): {
        0: [0.0855] * 7,
        15: [0.0771, 0.0780, 0.0807, 0.0848, 0.0894, 0.0934, 0.0950],
        30: [0.0696, 0.0711, 0.0755, 0.0826, 0.0918, 0.1015, 0.1064],
        45: [0.0632, 0.0649, 0.0701, 0.0790, 0.0915, 0.1079, 0.1249],
        60: [0.0577, 0.0595, 0.0648, 0.0739, 0.0868, 0.1027, 0.1148],
        75: [0.0529, 0.0545, 0.0593, 0.0673, 0.0775, 0.0872, 0.0915],
    },
    (0.70, 0.95, 0.10, 0.70, 50.0): {
        0: [0.6467] * 7,
        15: [0.6790, 0.6750, 0.6645, 0.6513, 0.6396, 0.6323, 0.6299],
        30: [0.7256, 0.7164, 0.6929, 0.6647, 0.6424, 0.6327, 0.6323],
        45: [0.7856, 0.7703, 0.7317, 0.6869, 0.6534, 0.6460, 0.6685],
        60: [0.8584, 0.8361, 0.7809, 0.7176, 0.6689, 0.6497, 0.6565],
        75: [0.9450, 0.9154, 0.8424, 0.7587, 0.6902, 0.6489, 0.6357],
    },
    (0.10, 0.60, -0.20, 0.10, 20.0): {
        0: [0.2316] * 7,
        15: [0.1990, 0.2019, 0.2105, 0.2243, 0.2418, 0.2608, 0.2733],
        30: [0.1739, 0.1779, 0.1898, 0.2092, 0.2344, 0.2610, 0.2760],
        45: [0.1573, 0.1616, 0.1744, 0.1952, 0.2216, 0.2464, 0.2574],
        60: [0.1515, 0.1558, 0.1685, 0.1891, 0.2144, 0.2371, 0.2465],
        75: [0.1660, 0.1704, 0.1835, 0.2043, 0.2293, 0.2510, 0.2598],
    },
}


@pytest.mark.parametrize("case", list(RAMI_RPV))
def test_rpv_reproduces_the_rami_iv_tables(case):
    rho, k, theta, rho_hs, sza = case
    phi_rami = np.arange(0.0, 180.1, 30.0)
    for view_zenith, row in RAMI_RPV[case].items():
        brf = math.pi * rpv(sza, view_zenith, 180.0 - phi_rami, rho / math.pi, k, theta, rho_hs)
        np.testing.assert_allclose(brf, row, rtol=0, atol=5.1e-5)


def _rpv_reference(ti, tv, phi, rho0, k, theta, rho_c):
    # Rahman et al. (1993) as printed: F(g) with -2 Theta cos(pi - g), g from the unit vectors.
    mu_i, mu_v = math.cos(math.radians(ti)), math.cos(math.radians(tv))
    g = math.acos(max(-1.0, min(1.0, _dot(_direction(ti, 0.0), _direction(tv, phi)))))
    minnaert = mu_i ** (k - 1) * mu_v ** (k - 1) / (mu_i + mu_v) ** (1 - k)
    hg = (1 - theta**2) / (1 + theta**2 - 2 * theta * math.cos(math.pi - g)) ** 1.5
    tan_i, tan_v = math.tan(math.radians(ti)), math.tan(math.radians(tv))
    big_g = math.sqrt(max(0.0, tan_i**2 + tan_v**2 - 2 * tan_i * tan_v * math.cos(math.radians(phi))))
    return rho0 * minnaert * hg * (1 + (1 - rho_c) / (1 + big_g))


@pytest.mark.parametrize(("ti", "tv", "phi"), HAND_GEOMETRIES)
def test_rpv_equals_an_independent_scalar_implementation(ti, tv, phi):
    for params in [(0.05, 0.7, -0.2, 0.3), (0.2, 1.3, 0.35, 1.0), (0.01, 0.2, -0.9, 0.0)]:
        assert rpv(ti, tv, phi, *params) == pytest.approx(_rpv_reference(ti, tv, phi, *params), rel=1e-11)


@given(zenith, zenith, azimuth)
def test_rpv_is_lambertian_for_k_1_theta_0_rho_c_1(ti, tv, phi):
    # M = 1 (k = 1), F = 1 (theta = 0), 1 + R = 1 (rho_c = 1).
    assert rpv(ti, tv, phi, rho0=0.07, k=1.0, theta=0.0, rho_c=1.0) == pytest.approx(0.07, rel=1e-14)


def test_rpv_hot_spot_and_asymmetry():
    theta_r, phi = np.meshgrid(np.arange(0.0, 89.01, 0.1), np.arange(0.0, 180.01, 0.5), indexing="ij")
    # With k = 1 and theta = 0 only the hot-spot factor varies: 1 + (1 - rho_c)/(1 + G) is largest
    # where G = 0, i.e. at tv = ti, phi = 0, with the value 2 - rho_c.
    values = rpv(30.0, theta_r, phi, rho0=0.1, k=1.0, theta=0.0, rho_c=0.4)
    best = np.unravel_index(np.argmax(values), values.shape)
    assert (theta_r[best], phi[best]) == pytest.approx((30.0, 0.0))
    assert values[best] == pytest.approx(0.1 * (2 - 0.4), rel=1e-12)
    # theta < 0 (backward scattering) only strengthens it; theta > 0 moves the maximum forward.
    backward = rpv(30.0, theta_r, phi, rho0=0.1, k=1.0, theta=-0.3, rho_c=0.4)
    best = np.unravel_index(np.argmax(backward), backward.shape)
    assert (theta_r[best], phi[best]) == pytest.approx((30.0, 0.0))
    forward = rpv(30.0, theta_r, phi, rho0=0.1, k=1.0, theta=0.3, rho_c=1.0)
    assert phi[np.unravel_index(np.argmax(forward), forward.shape)] == 180.0
    # At the hot spot (g = 0) and in the specular direction: F = (1 - T)/(1 + T)^2 and, with
    # cos g = cos 60 there, (1 - T^2)/(1 + T + T^2)^1.5.
    t = -0.3
    assert rpv(30, 30, 0, 1.0, 1.0, t, 1.0) == pytest.approx((1 - t) / (1 + t) ** 2, rel=1e-12)
    assert rpv(30, 30, 180, 1.0, 1.0, t, 1.0) == pytest.approx((1 - t**2) / (1 + t + t**2) ** 1.5, rel=1e-12)
    # No hot spot for rho_c = 1 and theta = 0: the azimuth does not matter.
    flat = rpv(30.0, 50.0, np.linspace(0, 180, 7), rho0=0.1, k=0.6, theta=0.0, rho_c=1.0)
    np.testing.assert_allclose(flat, flat[0], rtol=1e-13)


def test_rpv_minnaert_term_bowl_and_bell():
    # k < 1: brighter towards grazing (bowl); k > 1: darker (bell). For a nadir sun, theta = 0 and
    # rho_c = 1 the model is rho0 (cos tv (1 + cos tv))^(k - 1).
    tv = np.linspace(0, 80, 9)
    bowl = rpv(0.0, tv, 0.0, 0.1, 0.5, 0.0, 1.0)
    bell = rpv(0.0, tv, 0.0, 0.1, 1.5, 0.0, 1.0)
    assert np.all(np.diff(bowl) > 0) and np.all(np.diff(bell) < 0)
    mu = np.cos(np.radians(tv))
    np.testing.assert_allclose(bowl, 0.1 * (mu * (1 + mu)) ** -0.5, rtol=1e-12)


def test_rpv_model_is_linear_in_rho0_only():
    model = get_model("rpv")
    assert model.linear == ("rho0",) and model.shape_names == ("k", "theta", "rho_c")
    assert "rpv" in SURFACE_MODELS
    geometry = ScatteringGeometry(np.array([20.0, 50.0]), np.array([35.0, 10.0]), np.array([0.0, 150.0]))
    shape = {"k": 0.8, "theta": -0.15, "rho_c": 0.2}
    (basis,) = model.terms(geometry, shape)
    np.testing.assert_allclose(0.04 * basis, model.evaluate(geometry, rho0=0.04, **shape), rtol=1e-14)
    bounds = model.bounds
    assert bounds == {"rho0": (0.0, MAX_INTENSITY), "k": (0.0, 2.0), "theta": (-1.0, 1.0), "rho_c": (0.0, 1.0)}
    assert model.parameter("k").lower_open


# --- Domain edges, warnings and array kinds -------------------------------------------------


EDGE_ANGLES = [0.0, 1e-9, 0.5, 30.0, 45.0, 60.0, 89.0, 89.999, 89.999999]


def _edge_values():
    ti, tv, phi = np.meshgrid(EDGE_ANGLES, EDGE_ANGLES, [0.0, 1e-9, 45.0, 90.0, 179.999, 180.0], indexing="ij")
    values = [kernel(ti, tv, phi) for kernel in KERNELS.values()]
    values += [get_model(name)(ti, tv, phi, f_iso=0.1, f_vol=0.05, f_geo=0.02) for name in MODEL_NAMES]
    for k, theta, rho_c in [(1e-6, -1.0, 0.0), (2.0, 1.0, 1.0), (0.5, -0.999999, 0.0), (1.0, 0.0, 1.0)]:
        values.append(rpv(ti, tv, phi, 0.1, k, theta, rho_c))
    return values


def test_finite_without_warnings_at_nadir_hot_spot_and_grazing():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        values = _edge_values()
    for value in values:
        assert np.all(np.isfinite(value))


def test_finite_without_warnings_on_a_dense_grid():
    theta = np.concatenate([np.linspace(0.0, 89.0, 90), [89.5, 89.9, 89.99, 89.999]])
    ti, tv, phi = np.meshgrid(theta, theta, np.linspace(0.0, 180.0, 37), indexing="ij")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for kernel in KERNELS.values():
            assert np.all(np.isfinite(kernel(ti, tv, phi)))
        assert np.all(np.isfinite(rpv(ti, tv, phi, 0.05, 0.3, -0.5, 0.1)))


@pytest.fixture
def angles():
    rng = np.random.default_rng(11)
    return rng.uniform(0, 85, (3, 40, 50)) * np.array([1, 1, 180 / 85])[:, None, None]


def _functions():
    return [
        *KERNELS.values(),
        lambda ti, tv, phi: li_dense(ti, tv, phi, b_r=1.0),
        *(
            (lambda ti, tv, phi, name=name: get_model(name)(ti, tv, phi, f_iso=0.1, f_vol=0.05, f_geo=0.02))
            for name in MODEL_NAMES
        ),
        lambda ti, tv, phi: kernel_driven(ti, tv, phi, 0.1, 0.05, 0.02, volume="ross_thin", geometric="li_dense"),
        lambda ti, tv, phi: rpv(ti, tv, phi, rho0=0.05, k=0.7, theta=-0.2, rho_c=0.3),
    ]


@pytest.mark.parametrize("function", _functions())
def test_numpy_dask_xarray_and_scalar_inputs_agree(function, angles, no_compute, array_kinds_agree):
    array_kinds_agree(function, angles, rtol=1e-14)


def test_xarray_weights_per_band_share_the_geometry():
    theta_r = xr.DataArray(np.linspace(0, 60, 7), dims="x")
    band = {"band": [469, 555, 645]}
    f_iso = xr.DataArray([0.03, 0.05, 0.04], dims="band", coords=band)
    f_vol = xr.DataArray([0.01, 0.02, 0.03], dims="band", coords=band)
    result = kernel_driven(30.0, theta_r, 150.0, f_iso=f_iso, f_vol=f_vol, f_geo=0.005)
    assert set(result.dims) == {"x", "band"} and result.attrs["units"] == "sr^-1"
    for i, wavelength in enumerate(band["band"]):
        np.testing.assert_allclose(
            result.sel(band=wavelength).values,
            kernel_driven(30.0, theta_r.values, 150.0, float(f_iso[i]), float(f_vol[i]), 0.005),
            rtol=1e-14,
        )
    rho0 = xr.DataArray([0.02, 0.04], dims="band")
    assert rpv(30.0, theta_r, 10.0, rho0, 0.8, -0.1, 0.5).dims == ("x", "band")


# --- Independent implementation from PyPI (pydirectional, a test dependency) ------------------


def _pydirectional():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its import warns about pydantic v1 APIs
        return (importlib.import_module("pydirectional.brdf_forward_model.RTLS"),
                importlib.import_module("pydirectional.brdf_forward_model.RPV"))


@pytest.mark.parametrize("volume", VOLUME_KERNELS)
@pytest.mark.parametrize(("geometric", "b_r"), [("li_sparse", 1.0), ("li_dense", 2.5)])
def test_kernels_agree_with_pydirectional(volume, geometric, b_r):
    # pydirectional (NPL) ports P. Lewis' UCL kernel code: RossType Thick/Thin, LiType
    # Sparse/Dense with RecipFlag (reciprocal forms), hot spot at raa = 0.
    rtls, _ = _pydirectional()
    rng = np.random.default_rng(3)
    sza, vza, raa = rng.uniform(0, 85, 1000), rng.uniform(0, 85, 1000), rng.uniform(0, 180, 1000)
    oracle = rtls.RTLSBRDF(sza=sza, vza=vza, raa=raa, RossType=volume.split("_")[1].title(),
                           LiType=geometric.split("_")[1].title(), BR=b_r, HB=2.0, RecipFlag=True)
    np.testing.assert_allclose(KERNELS[volume](sza, vza, raa), oracle.volumetric, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(KERNELS[geometric](sza, vza, raa), oracle.geometric, rtol=1e-12, atol=1e-12)


def test_rpv_agrees_with_pydirectional():
    # pydirectional's RPVBRDF returns the reflectance factor (= pi BRDF); it allows 0 < k <= 1.
    _, rpv_module = _pydirectional()
    rng = np.random.default_rng(4)
    sza, vza, raa = rng.uniform(0, 85, 500), rng.uniform(0, 85, 500), rng.uniform(0, 180, 500)
    oracle = rpv_module.RPVBRDF(sza=sza, vza=vza, raa=raa)
    for rho, k, theta, rho_c in [(0.2, 0.8, -0.15, 0.3), (0.05, 0.6, 0.2, 0.9), (0.5, 1.0, 0.0, 0.0)]:
        np.testing.assert_allclose(
            math.pi * rpv(sza, vza, raa, rho / math.pi, k, theta, rho_c),
            oracle.return_BRF(rho, k, theta, rho_c),
            rtol=1e-12,
        )
