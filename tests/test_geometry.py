"""Geometry: check values from the papers, closed forms and properties over the angle domain."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from brdfcorr.geometry import (
    ScatteringGeometry,
    facet_inclination,
    local_incidence,
    relative_azimuth,
    specular_deviation,
)

zenith = st.floats(0.0, 90.0, exclude_max=True)
azimuth = st.floats(0.0, 180.0)


@pytest.mark.parametrize(
    ("theta_i", "theta_r", "phi", "alpha"),
    [
        # Paper 003, section 4: "a surface facet with normal alpha = 5 deg is needed" to send light
        # from 45 deg to 35 or 55 deg in the principal plane, or to 45 deg at phi = 170 ...
        (45.0, 35.0, 180.0, 5.0),
        (45.0, 55.0, 180.0, 5.0),
        (45.0, 45.0, 170.0, 5.0),
        # ... 10.6 deg for theta_i = theta_r = 65, phi = 170; 2.9 deg at 30/30/170; 5 deg at 65->75.
        (65.0, 65.0, 170.0, 10.6),
        (30.0, 30.0, 170.0, 2.9),
        (65.0, 75.0, 180.0, 5.0),
    ],
)
def test_facet_inclination_paper_003_section_4(theta_i, theta_r, phi, alpha):
    # The paper quotes one decimal (and "5 deg" for 4.98 deg): compare at that precision.
    assert facet_inclination(theta_i, theta_r, phi) == pytest.approx(alpha, abs=0.05)


def test_facet_inclination_equals_paper_003_eq3_arccos_form():
    # Independent evaluation of eq. 3 as printed (arccos form) on a grid away from alpha ~ 0.
    ti, tr, phi = np.meshgrid(np.arange(0, 90, 7.0), np.arange(0, 90, 11.0), np.arange(0, 181, 15.0))
    ti_r, tr_r, phi_r = np.radians(ti), np.radians(tr), np.radians(phi)
    cos_alpha = (np.cos(ti_r) + np.cos(tr_r)) / np.sqrt(
        (np.cos(phi_r) * np.sin(tr_r) + np.sin(ti_r)) ** 2
        + np.sin(phi_r) ** 2 * np.sin(tr_r) ** 2
        + (np.cos(ti_r) + np.cos(tr_r)) ** 2
    )
    expected = np.degrees(np.arccos(np.clip(cos_alpha, -1, 1)))
    np.testing.assert_allclose(facet_inclination(ti, tr, phi), expected, atol=1e-6)


def test_specular_deviation_paper_000_example():
    # Paper 000, after eq. 2: (40, 50, 180) gives psi = 10 deg; the specular direction gives 0.
    assert specular_deviation(40.0, 50.0, 180.0) == pytest.approx(10.0, abs=1e-9)
    assert specular_deviation(33.0, 33.0, 180.0) == pytest.approx(0.0, abs=1e-9)


def test_specular_deviation_equals_paper_000_eq2_arccos_form():
    ti, tr, phi = np.meshgrid(np.arange(0, 90, 7.0), np.arange(0, 90, 11.0), np.arange(0, 181, 15.0))
    ti_r, tr_r, phi_r = np.radians(ti), np.radians(tr), np.radians(phi)
    cos_psi = -np.sin(ti_r) * np.sin(tr_r) * np.cos(phi_r) + np.cos(ti_r) * np.cos(tr_r)
    expected = np.degrees(np.arccos(np.clip(cos_psi, -1, 1)))
    np.testing.assert_allclose(specular_deviation(ti, tr, phi), expected, atol=1e-5)


@given(zenith, zenith)
def test_psi_is_twice_alpha_in_the_principal_plane(theta_i, theta_r):
    # Paper 000, "In the principal plane 2 alpha = psi" (forward half, phi = 180).
    assert specular_deviation(theta_i, theta_r, 180.0) == pytest.approx(
        2.0 * facet_inclination(theta_i, theta_r, 180.0), abs=1e-9
    )


@given(zenith)
def test_local_incidence_in_specular_direction_is_the_sun_zenith(theta):
    assert local_incidence(theta, theta, 180.0) == pytest.approx(theta, abs=1e-9)


@given(zenith, zenith, azimuth)
def test_local_incidence_is_half_the_sun_view_angle(theta_i, theta_r, phi):
    # Closed form: cos(2 beta) = i . r with i, r the unit vectors to sun and sensor.
    ti, tr, ph = np.radians([theta_i, theta_r, phi])
    cos_sun_view = np.sin(ti) * np.sin(tr) * np.cos(ph) + np.cos(ti) * np.cos(tr)
    beta = local_incidence(theta_i, theta_r, phi)
    assert np.cos(np.radians(2 * beta)) == pytest.approx(cos_sun_view, abs=1e-9)


@given(zenith, zenith, azimuth)
def test_angles_in_range_and_reciprocal(theta_i, theta_r, phi):
    forward = ScatteringGeometry(theta_i, theta_r, phi)
    reverse = ScatteringGeometry(theta_r, theta_i, phi)
    assert 0.0 <= forward.alpha < 90.0
    assert 0.0 <= forward.psi <= 180.0
    assert 0.0 <= forward.local_incidence < 90.0
    for name in ("alpha", "psi", "local_incidence"):
        assert getattr(forward, name) == pytest.approx(getattr(reverse, name), abs=1e-9)


@pytest.mark.parametrize(
    ("saa", "vaa", "phi"),
    [(135.0, 315.0, 180.0), (10.0, 350.0, 20.0), (350.0, 10.0, 20.0), (90.0, 90.0, 0.0),
     (0.0, 180.0, 180.0), (-30.0, 30.0, 60.0), (720.0, 90.0, 90.0)],
)
def test_relative_azimuth_folds_into_0_180(saa, vaa, phi):
    assert relative_azimuth(saa, vaa) == pytest.approx(phi)


@given(st.floats(-720, 720), st.floats(-720, 720))
def test_relative_azimuth_symmetric_and_bounded(saa, vaa):
    phi = relative_azimuth(saa, vaa)
    assert 0.0 <= phi <= 180.0
    assert phi == pytest.approx(relative_azimuth(vaa, saa), abs=1e-9)
