"""Two-lobe models: the sum of a registered backscatter model and a specular lobe."""

import numpy as np
import pytest

from brdfcorr.errors import ParameterError
from brdfcorr.fit.goniometer import fit_brdf
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.models import REGISTRY, SURFACE_MODELS, empirical, get_model, kernel_driven, rpv, torrance_sparrow
from brdfcorr.models.rpv import RPV
from brdfcorr.models.torrance_sparrow import TORRANCE_SPARROW
from brdfcorr.models.two_lobe import TWO_LOBE_MODELS, two_lobe

KERNELS = {"f_iso": 0.03, "f_vol": 0.02, "f_geo": 0.004}
RPV_PART = {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5}
TS_LOBE = {"t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25}  # paper 003, Table 1 (roof tile)
PEAK = {"a": 0.02, "b": 1.0, "c": 0.05}
PARAMS = {
    "ross_li_ts": {**KERNELS, **TS_LOBE},
    "ross_li_peak": {**KERNELS, **PEAK},
    "rpv_peak": {**RPV_PART, **PEAK},
}

rng = np.random.default_rng(3)
THETA_I, THETA_R, PHI = rng.uniform(0, 75, 500), rng.uniform(0, 75, 500), rng.uniform(0, 180, 500)


def _parts(name, ti, tr, phi):
    """The two parts evaluated independently by the public one-lobe functions."""
    p = PARAMS[name]
    if name == "ross_li_ts":
        return kernel_driven(ti, tr, phi, **KERNELS) + torrance_sparrow(ti, tr, phi, t0=0.0, **TS_LOBE)
    if name == "ross_li_peak":
        return kernel_driven(ti, tr, phi, **KERNELS) + empirical(ti, tr, phi, **PEAK)
    return rpv(ti, tr, phi, **{key: p[key] for key in RPV_PART}) + empirical(ti, tr, phi, **PEAK)


def test_the_two_lobe_models_are_registered_surface_models():
    assert {model.name for model in TWO_LOBE_MODELS} == set(PARAMS)
    assert set(PARAMS) <= set(SURFACE_MODELS) <= set(REGISTRY)


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_a_two_lobe_model_is_the_sum_of_its_parts(name):
    np.testing.assert_allclose(get_model(name)(THETA_I, THETA_R, PHI, **PARAMS[name]),
                               _parts(name, THETA_I, THETA_R, PHI), rtol=1e-12)


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_two_lobe_models_are_reciprocal_and_non_negative(name):
    model = get_model(name)
    forward = model(THETA_I, THETA_R, PHI, **PARAMS[name])
    np.testing.assert_allclose(forward, model(THETA_R, THETA_I, PHI, **PARAMS[name]), rtol=1e-12)
    # The lobe only adds: with the backscatter part at physical weights (non-negative on the whole
    # domain, as the kernel and RPV tests show for these values), any lobe intensity >= 0 keeps the
    # model >= that part.
    lobe = model.linear[-1]
    diffuse = model(THETA_I, THETA_R, PHI, **{**PARAMS[name], lobe: 0.0})
    assert np.all(diffuse >= 0)
    for intensity in rng.uniform(0, 1, 10):
        assert np.all(model(THETA_I, THETA_R, PHI, **{**PARAMS[name], lobe: intensity}) >= diffuse)


@pytest.mark.parametrize("name", sorted(PARAMS))
def test_parameters_keep_the_units_and_bounds_of_their_parts(name):
    model = get_model(name)
    diffuse, lobe = {"ross_li_ts": ("ross_thick_li_sparse", "torrance_sparrow"),
                     "ross_li_peak": ("ross_thick_li_sparse", "empirical"), "rpv_peak": ("rpv", "empirical")}[name]
    parts = {p.name: p for part in (lobe, diffuse) for p in get_model(part).parameters}
    for parameter in model.parameters:
        assert parameter == parts[parameter.name]
    with pytest.raises(ParameterError, match=model.linear[-1]):
        model(30, 30, 180, **{**PARAMS[name], model.linear[-1]: -0.1})


def test_parts_with_a_shared_parameter_name_are_refused():
    # RPV's k (Minnaert exponent) is not Torrance-Sparrow's k (absorption index).
    with pytest.raises(ValueError, match="share the parameter"):
        two_lobe("rpv_ts", "", RPV, TORRANCE_SPARROW, ("t1",))


def test_a_goniometer_fit_recovers_a_two_lobe_surface():
    # Noise-free measurements on a grid of both halves: the fit must return the truth.
    ti, tr, phi = (a.ravel() for a in np.meshgrid([0, 15, 30, 45, 60], [0, 10, 20, 30, 40, 50, 60],
                                                    [0, 45, 90, 135, 160, 180], indexing="ij"))
    truth = PARAMS["ross_li_ts"]
    result = fit_brdf("ross_li_ts", ti, tr, phi, get_model("ross_li_ts")(ti, tr, phi, **truth), fixed={"k": 0.25})
    for name, value in truth.items():
        assert result.params[name] == pytest.approx(value, rel=1e-4, abs=1e-7), name


@pytest.mark.parametrize("seed", range(5))
def test_an_imagery_fit_recovers_the_lobe_shape_and_the_intensities_per_band(seed):
    # Noise-free: the truth is the exact minimum (objective 0), so the fit must end there to within
    # the Newton polish's convergence step (1e-3 relative); t1 trades with n along the Fresnel
    # factor (t1 19 % high at n = 1.65, 7 % low), hence three times that for the intensities.
    # Seeds 1, 3 and 4 once stopped in that n-t1 valley: the grid's best point lay at n = 1.05.
    n, rng = 3000, np.random.default_rng(seed)
    ti, tr, phi = rng.uniform(20, 50, n), rng.uniform(0, 40, n), rng.choice([5.0, 175.0], n) + rng.uniform(-5, 5, n)
    model = get_model("ross_li_ts")
    bands = [{**PARAMS["ross_li_ts"]}, {**PARAMS["ross_li_ts"], "f_iso": 0.1, "f_vol": 0.05, "t1": 0.4}]
    brdf = np.column_stack([model(ti, tr, phi, **band) for band in bands])
    result = fit_class_samples("ross_li_ts", ti, tr, phi, brdf)
    assert result["at_edge"] == [] and result["if_held"] is None
    assert result["params"]["w"][0] == pytest.approx(0.0362, rel=1e-3)
    assert result["params"]["n"][0] == pytest.approx(1.77, rel=1e-3)
    np.testing.assert_allclose(result["params"]["f_iso"], [0.03, 0.1], rtol=3e-3)
    np.testing.assert_allclose(result["params"]["t1"], [0.2, 0.4], rtol=3e-3)
