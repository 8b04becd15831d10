"""The V-cavity simulation of paper 000 against the analytic Torrance-Sparrow model.

Tolerances come from ``benchmarks/bench_simulate.py`` (paper 000 fig. 2 geometries, normalized TS
value > 0.1): default grid (step = sigma / 2, cutoff 5, horizontal pole) max error 0.16 %, caused
by the finite width sigma of the facet peak blurring the kink of G (it halves with sigma);
step = sigma: 3.1 %; step = 1.5 sigma: 60 %; a grid with its pole at the zenith: 3.2 % at the
specular point.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from brdfcorr.analysis.simulate import FacetGrid, facet_visible_fraction, paper_sigma, simulate_vcavity
from brdfcorr.errors import ParameterError
from brdfcorr.models import geometric_attenuation, torrance_sparrow

ROUGHNESSES = (0.01, 0.05, 0.15)
# Paper 000 fig. 2: principal plane at theta_i = 10, 45, 75 deg and phi = 150 deg at 45 deg.
CUTS = ((10.0, 180.0), (45.0, 180.0), (75.0, 180.0), (45.0, 150.0))
VIEW = np.arange(0.0, 86.0, 5.0)


def analytic_normalized(theta_i, theta_r, phi, w):
    """TS specular part with constant Fresnel reflectance, normalized at 45/45/180 (paper 000)."""

    def ts(ti, tr, ph):
        return torrance_sparrow(ti, tr, ph, t0=0.0, t1=1.0, w=w, n=1e9, k=0.0)

    return ts(theta_i, theta_r, phi) / ts(45.0, 45.0, 180.0)


@pytest.mark.parametrize("w", ROUGHNESSES)
def test_simulation_reproduces_ts_in_and_out_of_the_principal_plane(w):
    checked = 0
    for theta_i, phi in CUTS:
        simulated = simulate_vcavity(theta_i, VIEW, phi, w, normalize=True)
        expected = analytic_normalized(theta_i, VIEW, phi, w)
        mask = expected > 0.1  # the criterion
        checked += mask.sum()
        # 0.5 %: three times the benchmark's worst case for the default grid (0.16 %).
        np.testing.assert_allclose(simulated[mask], expected[mask], rtol=5e-3)
    assert checked >= 20


def test_simulation_off_plane_and_shadowed_geometries():
    # Geometries where G < 1 (backscatter, far off the principal plane) check the ray-intersection
    # masking against the closed-form G of the analytic model.
    geometries = [(0.0, 65.0, 0.0), (60.0, 70.0, 0.0), (60.0, 60.0, 90.0), (30.0, 80.0, 120.0)]
    for theta_i, theta_r, phi in geometries:
        assert geometric_attenuation(theta_i, theta_r, phi) < 0.95
        simulated = simulate_vcavity(theta_i, theta_r, phi, 0.01)
        expected = torrance_sparrow(theta_i, theta_r, phi, t0=0.0, t1=0.25, w=0.01, n=1e9, k=0.0)
        assert simulated == pytest.approx(expected, rel=2e-3)


def test_absolute_scale_is_the_ts_jacobian_with_fresnel():
    # Per unit facet albedo the simulated surface BRDF is F G D / (4 cos ti cos tr): TS with
    # t1 = 1/4 (the Jacobian dOmega_r = 4 cos(beta) dOmega_h), here with a real Fresnel term.
    theta_r = np.array([20.0, 45.0, 60.0])
    simulated = simulate_vcavity(45.0, theta_r, 170.0, 0.05, n=1.5, k=0.25)
    expected = torrance_sparrow(45.0, theta_r, 170.0, t0=0.0, t1=0.25, w=0.05, n=1.5, k=0.25)
    np.testing.assert_allclose(simulated, expected, rtol=2e-3)


def test_simulation_is_reciprocal():
    forward = simulate_vcavity([20.0, 35.0], [55.0, 70.0], 160.0, 0.05)
    backward = simulate_vcavity([55.0, 70.0], [20.0, 35.0], 160.0, 0.05)
    np.testing.assert_allclose(forward, backward, rtol=2e-3)


def test_coarse_grids_fail_as_the_benchmark_says():
    # The check is sensitive: a grid step of 1.5 sigma or a zenith-pole grid misses by percents.
    expected = analytic_normalized(45.0, 30.0, 180.0, 0.05)
    coarse = simulate_vcavity(45.0, 30.0, 180.0, 0.05, grid=FacetGrid(step_fraction=1.5), normalize=True)
    assert abs(coarse / expected - 1.0) > 0.05
    specular = simulate_vcavity(45.0, 45.0, 180.0, 0.05)
    zenith_pole = simulate_vcavity(45.0, 45.0, 180.0, 0.05, grid=FacetGrid(pole="zenith"))
    assert specular == pytest.approx(0.25 * torrance_sparrow(45, 45, 180, 0, 1, 0.05, 1e9, 0), rel=1e-3)
    assert abs(zenith_pole / specular - 1.0) > 0.01


@settings(max_examples=200, deadline=None)
@given(
    theta=st.floats(0.0, 89.0),
    azimuth=st.floats(-180.0, 180.0),
    alpha=st.floats(0.0, 89.0),
)
def test_ray_intersection_equals_the_closed_form_v_cavity_term(theta, azimuth, alpha):
    # Independent closed form (Torrance & Sparrow; Blinn 1977): min(1, 2 cos(a) cos(theta) / n.d),
    # for a direction d facing the facet with normal n = (sin a, 0, cos a) in the (u, z) plane.
    d = np.array([math.sin(math.radians(theta)) * math.cos(math.radians(azimuth)), math.cos(math.radians(theta))])
    a = math.radians(alpha)
    facing = d[0] * math.sin(a) + d[1] * math.cos(a)
    fraction = facet_visible_fraction(d[0], d[1], alpha)
    if facing <= 0.0:
        assert fraction == 0.0  # the facet faces away
    elif facing > 1e-9:
        assert fraction == pytest.approx(min(1.0, 2 * math.cos(a) * d[1] / facing), abs=1e-9)


def test_paper_sigma_and_bad_settings():
    assert paper_sigma(0.01) == paper_sigma(0.05) == 0.07
    assert paper_sigma(0.15) == 0.03
    with pytest.raises(ParameterError, match="step_fraction"):
        simulate_vcavity(45, 45, 180, 0.05, grid=FacetGrid(step_fraction=0))
    with pytest.raises(ParameterError, match="zenith"):
        simulate_vcavity(45, 90, 180, 0.05)
    with pytest.raises(ParameterError, match="pole"):
        simulate_vcavity(45, 45, 180, 0.05, grid=FacetGrid(pole="north"))
