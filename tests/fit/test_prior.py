"""A coefficient set's kernel shape as a prior of an imagery fit (brdfcorr.fit.prior,
``fit-classes --prior``): the posterior against an independent augmented least-squares solution,
its limits, the published ratios, and what the table and the command keep."""

import numpy as np
import pytest
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import InputError, UnknownNameError
from brdfcorr.fit.prior import ShapePrior, prior_ratios, shape_posterior, with_shape_prior
from brdfcorr.params import ParameterTable

#: Roy et al. (2016), RSE 176, Table 1, red (BRF weights): f_iso, f_vol, f_geo.
ROY_RED = (0.1690, 0.0574, 0.0227)


def _kernel_fit(seed: int = 0, n: int = 200, noise: float = 0.004):
    """An ordinary least-squares fit of (f_iso, f_vol, f_geo) to noisy reflectances: the design
    (n, 3), the data, the estimate and its covariance sigma^2 (X^T X)^-1."""
    rng = np.random.default_rng(seed)
    design = np.column_stack([np.ones(n), rng.uniform(-0.2, 0.6, n), rng.uniform(-1.5, 0.0, n)])
    data = design @ np.array([0.05, 0.03, 0.004]) + rng.normal(0, noise, n)
    estimate = np.linalg.lstsq(design, data, rcond=None)[0]
    return design, data, estimate, noise**2 * np.linalg.inv(design.T @ design)


def test_the_posterior_is_the_augmented_least_squares_solution():
    # The fit's Gaussian likelihood is exact for a linear model: the posterior equals least squares
    # on the observations and the prior's two pseudo-observations, each weighted by its 1-sigma.
    design, data, estimate, covariance = _kernel_fit()
    ratios, spread, noise = np.array([0.4, 0.1]), 0.2, 0.004
    width = spread * estimate[0]
    prior_rows = np.array([[-ratios[0], 1.0, 0.0], [-ratios[1], 0.0, 1.0]]) / width
    augmented = np.vstack([design / noise, prior_rows])
    expected = np.linalg.lstsq(augmented, np.concatenate([data / noise, [0.0, 0.0]]), rcond=None)[0]
    weights, posterior = shape_posterior(estimate[None], covariance[None], ratios[None], spread)
    np.testing.assert_allclose(weights[0], expected, rtol=1e-9)
    np.testing.assert_allclose(posterior[0], np.linalg.inv(augmented.T @ augmented), rtol=1e-9)


def test_a_wide_prior_keeps_the_fit_and_a_narrow_one_takes_its_shape():
    _, _, estimate, covariance = _kernel_fit(seed=1)
    ratios = np.array([[0.4, 0.1]])
    wide, _ = shape_posterior(estimate[None], covariance[None], ratios, 1e6)
    np.testing.assert_allclose(wide[0], estimate, rtol=1e-6)
    narrow, narrow_covariance = shape_posterior(estimate[None], covariance[None], ratios, 1e-6)
    np.testing.assert_allclose(narrow[0, 1:] / narrow[0, 0], ratios[0], rtol=1e-5)
    # The prior adds information: no parameter is less certain than in the fit.
    assert np.all(np.diagonal(narrow_covariance[0]) <= np.diagonal(covariance) * (1 + 1e-9))


def test_prior_ratios_are_the_published_ones_at_a_band_centre():
    ratios = prior_ratios("roy2016", [660.0])  # between the red nodes (654.6 and 664.9 nm)
    np.testing.assert_allclose(ratios[0], [ROY_RED[1] / ROY_RED[0], ROY_RED[2] / ROY_RED[0]], rtol=1e-12)


def _table():
    """A fitted RTLSR class (per band, with its covariance), a class without a fit (a fallback's
    coefficients) and a Torrance-Sparrow class."""
    _, _, estimate, covariance = _kernel_fit(seed=2)
    weights = {"f_iso": [estimate[0]] * 2, "f_vol": [estimate[1]] * 2, "f_geo": [estimate[2]] * 2}
    errors = np.sqrt(np.diag(covariance))
    record = {"source": "imagery", "parameters": ["f_iso", "f_vol", "f_geo"], "n": [200, 200],
              "chi2_dof": [1.0, 1.0], "r2": [0.9, 0.9],
              "errors": {name: [float(errors[j])] * 2 for j, name in enumerate(weights)},
              "covariance": [covariance.tolist()] * 2}
    return ParameterTable(classes=[
        {"id": 1, "name": "grass", "model": "ross_thick_li_sparse", "wavelengths": [650.0, 860.0],
         "params": weights, "fit": record},
        {"id": 2, "name": "soil", "model": "ross_thick_li_sparse", "wavelengths": [650.0, 860.0],
         "params": weights},
        {"id": 3, "name": "roof", "model": "torrance_sparrow",
         "params": {"t0": 0.0245, "t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25}},
    ])


def test_only_fitted_kernel_classes_move_and_the_table_stays_valid(tmp_path):
    table = _table()
    moved = with_shape_prior(table, ShapePrior("roy2016", 0.2))
    grass = moved[1]
    assert grass.fit.source == "imagery + shape prior roy2016 (spread 0.2)"
    assert grass.params != table[1].params
    assert moved[2] == table[2] and moved[3] == table[3]
    errors = np.asarray(grass.fit.errors["f_vol"])
    assert np.all(errors <= np.asarray(table[1].fit.errors["f_vol"]))
    assert ParameterTable.load(moved.save(tmp_path / "table.yaml")) == moved


def test_the_spread_must_be_positive_and_the_set_known():
    with pytest.raises(InputError, match="spread"):
        ShapePrior("roy2016", 0.0)
    with pytest.raises(UnknownNameError, match="roy2015"):
        ShapePrior("roy2015")


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_strata_scene):
    root = tmp_path_factory.mktemp("prior")
    return {**write_strata_scene(root), "root": root}


def _fit_classes(files, *extra):
    return CliRunner().invoke(main, [str(a) for a in ("fit-classes", files["image"], "--angles", files["angles"],
                                                      "--classes", files["strata"], *extra)])


def test_fit_classes_with_a_prior_writes_the_posterior(files, tables_close):
    # Within the fit or on the fitted table: the same posterior (to the table's rounding).
    plain, prior = files["root"] / "plain.yaml", files["root"] / "prior.yaml"
    assert _fit_classes(files, "-o", plain).exit_code == 0
    result = _fit_classes(files, "--prior", "roy2016", "--prior-spread", "0.1", "-o", prior)
    assert result.exit_code == 0, result.output
    assert "shape prior roy2016 (spread 0.1): 2 fitted class(es) at their posterior" in result.output
    tables_close(ParameterTable.load(prior), with_shape_prior(ParameterTable.load(plain), ShapePrior("roy2016", 0.1)))


def test_a_prior_fits_the_classes_the_geometry_cannot_separate(files, tables_close):
    # With a condition limit no design meets, every stratum fails as ill-conditioned; with the
    # prior the shape is determined and the rail does not apply: the same posterior as above.
    result = _fit_classes(files, "--max-condition", "1", "-o", files["root"] / "never.yaml")
    assert result.exit_code == 2 and "ill-conditioned" in result.output
    rescued, plain = files["root"] / "rescued.yaml", files["root"] / "plain_again.yaml"
    result = _fit_classes(files, "--max-condition", "1", "--prior", "roy2016", "-o", rescued)
    assert result.exit_code == 0, result.output
    assert "ill-conditioned" not in result.output
    assert _fit_classes(files, "-o", plain).exit_code == 0
    tables_close(ParameterTable.load(rescued), with_shape_prior(ParameterTable.load(plain), ShapePrior("roy2016")))


@pytest.mark.parametrize("extra, message", [
    (("--prior-spread", "0.1"), "--prior-spread needs --prior"),
    (("--prior", "roy2015"), "roy2015"),
])
def test_a_prior_option_error_is_one_line_before_the_fit(files, extra, message):
    target = files["root"] / "never.yaml"
    result = _fit_classes(files, *extra, "-o", target)
    assert result.exit_code == 2 and message in result.output
    assert not target.exists()


def test_a_fit_without_noise_keeps_its_weights():
    # A noise-free fit has a zero covariance: the data decide alone, and nothing is inverted.
    fitted = np.array([[0.05, 0.03, 0.004], [0.0, 0.03, 0.004]])  # the second at the bound f_iso = 0
    weights, covariance = shape_posterior(fitted, np.zeros((2, 3, 3)), np.array([[0.4, 0.1]] * 2), 0.2)
    np.testing.assert_array_equal(weights, fitted)
    np.testing.assert_array_equal(covariance, np.zeros((2, 3, 3)))


def test_the_guard_rails_judge_the_posterior_not_the_fit():
    # A vegetated class (volume-dominated shape, f_vol/f_iso 0.5) under a narrow prior of the
    # opposite shape (no volume, strong geometric kernel): the posterior takes that shape, so it
    # explains less of the angular signal than the fit; its recorded R^2 is the posterior's own
    # (brdfcorr.fit.quality.fit_quality), and the angular rail refuses it.
    from brdfcorr.fit.classes import ClassFitWarning, ClassSamples, GuardRails, fit_one_class
    from brdfcorr.fit.quality import fit_quality
    from brdfcorr.geometry import relative_azimuth
    from brdfcorr.models import get_model

    rtlsr = get_model("ross_thick_li_sparse")
    rng = np.random.default_rng(5)
    n = 4000
    across = rng.uniform(-1, 1, n)
    angles = (rng.uniform(30, 50, n), 40.0 * np.abs(across),
              relative_azimuth(np.zeros(n), np.where(across < 0, 275.0, 95.0)))
    brdf = rtlsr(*(a[:, None] for a in angles), f_iso=np.array([0.02, 0.1]), f_vol=np.array([0.01, 0.05]),
                 f_geo=np.array([0.002, 0.01]))
    samples = ClassSamples(*angles, brdf * (1 + 0.02 * rng.standard_normal((n, 2))))
    guard = GuardRails(min_r2=0.9)
    plain = fit_one_class(1, "grass", rtlsr, samples, guard=guard)
    assert plain.status == "fitted"
    with pytest.warns(ClassFitWarning, match="angular R\\^2"):
        pulled = fit_one_class(1, "grass", rtlsr, samples, guard=guard,
                               prior=(ShapePrior("roy2016", 0.01), np.array([[0.0, 1.0]] * 2)))
    assert pulled.status == "uncorrected" and pulled.prior == "roy2016 (spread 0.01)"
    posterior = np.stack([pulled.params[name] for name in rtlsr.linear])
    expected = fit_quality(rtlsr, *angles, samples.brdf, posterior)
    np.testing.assert_allclose(pulled.angular_r2, expected["angular_r2"], rtol=1e-12)
    np.testing.assert_allclose(pulled.r2, expected["r2"], rtol=1e-12)
    assert np.all(pulled.angular_r2 < 0.9) and np.all(plain.angular_r2 > 0.95)


def test_a_wide_prior_leaves_a_fit_with_free_levels_judged_within_its_pixels():
    # Pixels seen four times, each at its own brightness (cover 0.5-2x): the fit with each pixel's
    # level free judges its views within pixels (angular R^2 near 1). A prior far too wide to move
    # the weights must leave what the guard rails read as it was. Judged on the samples' absolute
    # values instead, the pixels' levels counted as unexplained: a real composite's strata with
    # patch levels were left uncorrected under --prior (angular R^2 0.74 -> -0.06).
    from brdfcorr.fit.classes import ClassSamples, fit_one_class
    from brdfcorr.models import get_model

    rtlsr, rng = get_model("ross_thick_li_sparse"), np.random.default_rng(4)
    pixels, views = 500, 4
    sza, vza = rng.uniform(25, 45, (pixels, views)), rng.uniform(0, 40, (pixels, views))
    phi = rng.uniform(0, 180, (pixels, views))
    cover = rng.uniform(0.5, 2.0, (pixels, 1))
    brdf = rtlsr(sza, vza, phi, f_iso=0.05, f_vol=0.03, f_geo=0.008) * cover * (1 + 0.01 * rng.standard_normal(sza.shape))
    samples = ClassSamples(sza.ravel(), vza.ravel(), phi.ravel(), brdf.reshape(-1, 1),
                           group=np.repeat(np.arange(pixels), views), levels="pixel")
    plain = fit_one_class(1, "grass", rtlsr, samples)
    wide = fit_one_class(1, "grass", rtlsr, samples, prior=(ShapePrior("roy2016", 1e6), np.array([[0.5, 0.1]])))
    assert plain.status == wide.status == "fitted" and wide.prior == "roy2016 (spread 1e+06)"
    for name in rtlsr.linear:
        np.testing.assert_allclose(wide.params[name], plain.params[name], rtol=1e-6)
    assert plain.angular_r2[0] > 0.9
    np.testing.assert_allclose(wide.angular_r2, plain.angular_r2, atol=1e-3)
    np.testing.assert_allclose(wide.r2, plain.r2, atol=1e-3)
