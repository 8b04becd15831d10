"""The analyses of paper 003: shadowing impact, azimuthal width, albedo and energy checks.

Paper values and ours (0.5 deg grid unless stated; the worst case is the roof-tile peak on a
Lambertian albedo of 0.01, ``WORST_CASE_PARAMS``):

=====================================================  ===========  ===================
quantity                                               paper 003    brdfcorr
=====================================================  ===========  ===================
worst case, (theta_i, theta_r) = (0, 65): relative     14 %         13.7 %
worst case, zeniths <= 65, phi >= 90: relative         14 %         19.2 % (52.5, 65, 90)
worst case, zeniths <= 65, all phi: relative           14 %         24.4 % (24, 65, 0)
worst case, (0, 65): absolute [sr^-1]                  0.0019       0.00176
worst case, zeniths <= 70, phi >= 90: relative         34 %         34.0 %
worst case, zeniths <= 70: absolute [sr^-1]            0.0044       0.0041
worst case, zeniths <= 60, forward principal plane     0            0
worst case, zeniths <= 60, all phi                     0 ("none")   16 % (backscatter)
roof tile, zeniths <= 70, all phi                      10.3 %       10.6 %
red concrete                                           1.0 %        2.1 %
blue concrete                                          0.3 %        0.57 %
red aluminium                                          < 0.1 %      0.008 %
=====================================================  ===========  ===================

The paper's "no difference at all for zeniths <= 60 deg" holds for the 3-D V-cavity G only in the
forward principal plane (G(60, 60, 90) = 0.8, G(60, 60, 0) = 0.5); the concrete tiles come out
about twice the stated values on 0.5, 5 and 10 deg grids alike (unexplained; the paper does not
give its grid). Those two are asserted as documented disagreements, not tuned away.
"""

import math
import warnings

import numpy as np
import pytest

from brdfcorr.analysis.papers import (
    PAPER_SHADOWING,
    WORST_CASE_PARAMS,
    IntegrationAccuracyWarning,
    SimplifiedModelWarning,
    albedo,
    azimuthal_width,
    shadowing_impact,
    specular_albedo_bound,
    width_reduction,
)
from brdfcorr.errors import ParameterError
from brdfcorr.models import fresnel, geometric_attenuation, torrance_sparrow
from brdfcorr.models.materials import load_material

TABLE1 = ("roof_tile", "red_concrete", "blue_concrete", "red_aluminium")


# ---------------------------------------------------------------- shadowing impact (section 5)


def test_worst_case_at_nadir_illumination_65_deg():
    # Paper 003: 14 %, 0.0019 sr^-1 at (0, 65). The forward principal plane holds the maximum.
    impact = shadowing_impact(WORST_CASE_PARAMS, max_zenith=65.0, phi_range=(180.0, 180.0), step=0.5)
    assert impact.where_relative == (0.0, 65.0, 180.0)
    assert impact.max_relative == pytest.approx(0.14, abs=0.005)
    assert impact.max_absolute == pytest.approx(0.0019, rel=0.1)


def test_worst_case_up_to_65_deg_is_not_14_percent():
    # Documented disagreement (docs/models.md): the paper states 14 % as the maximum up to 65 deg;
    # the same model gives 13.7 % at (0, 65, 180) (above) but 19.2 % over phi >= 90 and 24.4 %
    # over all azimuths (backscatter), on the 0.5 deg grid.
    forward = shadowing_impact(WORST_CASE_PARAMS, max_zenith=65.0, phi_range=(90.0, 180.0), step=0.5)
    assert forward.max_relative == pytest.approx(0.192, abs=5e-4)
    assert forward.where_relative == (52.5, 65.0, 90.0)
    everywhere = shadowing_impact(WORST_CASE_PARAMS, max_zenith=65.0, step=0.5)
    assert everywhere.max_relative == pytest.approx(0.244, abs=5e-4)
    assert everywhere.where_relative == (24.0, 65.0, 0.0)


def test_worst_case_up_to_70_deg_forward_half():
    # Paper 003: 34 % and 0.0044 sr^-1 for zeniths <= 70 deg (measurements had phi >= 90).
    impact = shadowing_impact(WORST_CASE_PARAMS, max_zenith=70.0, phi_range=(90.0, 180.0), step=1.0)
    assert impact.max_relative == pytest.approx(0.34, abs=0.005)
    assert impact.max_absolute == pytest.approx(0.0044, rel=0.1)
    assert 70.0 in impact.where_relative[:2]  # on the edge of the range, as the paper implies


def test_no_difference_up_to_60_deg_only_in_the_forward_principal_plane():
    forward = shadowing_impact(WORST_CASE_PARAMS, max_zenith=60.0, phi_range=(180.0, 180.0), step=0.5)
    assert forward.max_relative < 1e-12 and forward.max_absolute < 1e-15
    # Documented disagreement: with the 3-D G the paper's "no difference at all" fails in
    # backscatter; the exact G there is 0.5 (closed form: 2 cos(alpha) cos(60) / cos(beta) with
    # alpha = beta = 60 in the hot spot direction).
    assert geometric_attenuation(60.0, 60.0, 0.0) == pytest.approx(0.5)
    everywhere = shadowing_impact(WORST_CASE_PARAMS, max_zenith=60.0, step=1.0)
    assert 0.05 < everywhere.max_relative < 0.2
    assert everywhere.where_relative[2] == 0.0


def test_table1_samples_shadowing_impact():
    values = {
        name: shadowing_impact(load_material(name).params, max_zenith=70.0, step=1.0).max_relative
        for name in TABLE1
    }
    assert values["roof_tile"] == pytest.approx(PAPER_SHADOWING["roof_tile"], abs=0.005)
    assert values["red_aluminium"] < PAPER_SHADOWING["red_aluminium"]
    # Concretes: same order of magnitude as the paper, about twice its values (see module notes).
    for name in ("red_concrete", "blue_concrete"):
        assert PAPER_SHADOWING[name] < values[name] < 2.5 * PAPER_SHADOWING[name]
    # The ranking the paper draws from it: broader peaks and weaker t0 suffer more.
    assert values["roof_tile"] > values["red_concrete"] > values["blue_concrete"] > values["red_aluminium"]


def test_shadowing_difference_is_never_negative_and_matches_a_direct_evaluation():
    impact = shadowing_impact(WORST_CASE_PARAMS, max_zenith=50.0, phi_range=(0.0, 60.0), step=2.0)
    full = torrance_sparrow(*impact.where_relative, **WORST_CASE_PARAMS)
    simple = torrance_sparrow(*impact.where_relative, **WORST_CASE_PARAMS, shadowing=False)
    assert impact.max_relative == pytest.approx((simple - full) / full, rel=1e-12)
    assert impact.max_relative >= 0.0


def test_shadowing_impact_rejects_bad_ranges():
    with pytest.raises(ParameterError, match="phi_range"):
        shadowing_impact(WORST_CASE_PARAMS, phi_range=(90.0, 200.0))
    with pytest.raises(ParameterError, match="w"):
        shadowing_impact({**WORST_CASE_PARAMS, "w": -1.0})


# ---------------------------------------------------------------- azimuthal width (fig. 3)


@pytest.mark.parametrize("name", TABLE1)
def test_azimuthal_width_reductions_of_table1_samples(name):
    # Paper 003: "reduces by about 50 % from 30 to 50 deg and by about 75 % from 30 to 65 deg".
    # Ours: 0.52-0.58 and 0.76-0.80 for these samples; "about" is taken as +-0.1 and +-0.06.
    result = width_reduction("torrance_sparrow", load_material(name).params)
    reductions = result["reductions"]
    assert reductions[(50.0, 50.0)] == pytest.approx(0.5, abs=0.1)
    assert reductions[(65.0, 70.0)] == pytest.approx(0.75, abs=0.06)
    widths = list(result["widths"].values())
    assert widths[0] > widths[1] > widths[2] > 0


@pytest.mark.parametrize("theta", [30.0, 50.0, 65.0])
def test_azimuthal_width_closed_form_for_the_empirical_model(theta):
    # Empirical model with b = 0 and t0: specular part a exp(-c^2 (psi/2)^2) is half at
    # psi_h = 2 sqrt(ln 2) / c; at theta_i = theta_r = theta, cos psi = cos^2 - sin^2 cos(phi), so
    # cos(phi_h) = (cos^2 theta - cos psi_h) / sin^2 theta and FWHM = 2 (180 - phi_h).
    c = 0.05
    psi_half = math.radians(2.0 * math.sqrt(math.log(2.0)) / c)
    t = math.radians(theta)
    phi_half = math.degrees(math.acos((math.cos(t) ** 2 - math.cos(psi_half)) / math.sin(t) ** 2))
    width = azimuthal_width("empirical", {"a": 0.3, "b": 0.0, "c": c, "t0": 0.1}, theta, theta)
    assert width == pytest.approx(2.0 * (180.0 - phi_half), rel=1e-8)


def test_azimuthal_width_infinite_when_never_half():
    # A very rough surface at 30 deg: the specular part stays above half its peak at phi = 0.
    assert azimuthal_width("torrance_sparrow", {"t0": 0, "t1": 1, "w": 0.002, "n": 1e9, "k": 0}, 30, 30) == math.inf


# ---------------------------------------------------------------- albedo and energy


@pytest.mark.parametrize("theta_i", [0.0, 45.0, 80.0])
def test_albedo_of_lambertian_is_pi_t0(theta_i):
    assert albedo("lambertian", theta_i, {"t0": 0.12}) == pytest.approx(math.pi * 0.12, rel=1e-12)


def test_albedo_of_a_narrow_ts_peak_matches_the_small_width_limit():
    # For a narrow peak (w large, G = 1 around it), rho = (4 t1 / cos ti) int F D cos(beta) dOmega_h
    # -> 4 t1 F(theta_i) int D dOmega_h = 4 pi t1 F(theta_i) / W^2, W = w in rad^-1 (Gaussian
    # integral). Corrections are O(1 / W^2) ~ 0.3 %.
    w, t1 = 0.3, 1.0
    big_w = w * 180.0 / math.pi
    for theta_i in (0.0, 30.0, 50.0):
        expected = 4.0 * math.pi * t1 * fresnel(math.cos(math.radians(theta_i)), 1.5, 0.0) / big_w**2
        got = albedo("torrance_sparrow", theta_i, {"t0": 0.0, "t1": t1, "w": w, "n": 1.5, "k": 0.0})
        assert got == pytest.approx(expected, rel=5e-3)


def test_energy_bound_holds_for_full_model_and_fails_for_simplified():
    params = {"t0": 0.0, "t1": 0.20, "w": 0.035, "n": 1e9, "k": 0.0}  # roof-tile peak, F = 1
    bound = specular_albedo_bound(params["t1"], params["w"])
    zeniths = np.array([0.0, 45.0, 70.0, 85.0, 89.0])
    full = albedo("torrance_sparrow", zeniths, params)
    assert np.all(full <= bound) and np.all(full > 0)
    with pytest.warns(SimplifiedModelWarning, match="albedo"):
        simplified = albedo("torrance_sparrow_simplified", zeniths, params)
    assert np.all(simplified >= full - 1e-12)  # G <= 1
    assert simplified[-1] > bound  # without G the albedo grows like 1 / cos(theta_i)
    assert simplified[-1] > 1.0  # ... past energy conservation


def test_library_materials_reflect_less_than_they_receive():
    for name in TABLE1:
        params = load_material(name).params
        rho = albedo("torrance_sparrow", [0.0, 60.0, 85.0], params)
        assert np.all((rho > math.pi * params["t0"]) & (rho < 1.0))


def test_specular_albedo_bound_closed_form_for_narrow_distribution():
    # int D cos(alpha) dOmega -> pi / W^2 for a narrow Gaussian (W in rad^-1).
    big_w = 0.5 * 180.0 / math.pi
    assert specular_albedo_bound(1.0, 0.5) == pytest.approx(8.0 * math.pi / big_w**2, rel=5e-3)


def test_albedo_warns_when_the_peak_is_too_narrow_for_the_panels():
    with pytest.warns(IntegrationAccuracyWarning, match="resolution"):
        albedo("specular_peak", 40.0, {"sigma": 0.2}, resolution=4.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        albedo("torrance_sparrow", 40.0, load_material("red_aluminium").params)


def test_albedo_rejects_bad_input():
    with pytest.raises(ParameterError, match="theta_i"):
        albedo("lambertian", 95.0, {"t0": 0.1})
    with pytest.raises(ParameterError, match="t0"):
        albedo("lambertian", 30.0, {"t0": -0.1})
