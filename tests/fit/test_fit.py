"""fit_brdf: closed forms, an independent optimizer, round trips with paper-003 materials, warnings."""

import warnings

import numpy as np
import pytest
from scipy.optimize import curve_fit, least_squares
from scipy.stats import chi2 as chi2_distribution

from brdfcorr.errors import BrdfcorrError, FitError, MeasurementError, ParameterError
from brdfcorr.fit.goniometer import (
    ErrorAnalysis,
    FitWarning,
    NonIdentifiableWarning,
    _problem,
    fit_brdf,
    fit_from,
    fit_measurements,
    format_with_error,
)
from brdfcorr.fit.identifiability import identifiability_messages
from brdfcorr.fit.measurements import filter_measurements
from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import REGISTRY, get_model
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable

ANGLES = goniometer_angles()
RELATIVE_NOISE = 0.04  # the lowest total error of the EGO measurements, paper 003 section 3
PAPER_K = {"k": 0.25}  # paper 003 section 4: k fixed at 0.25 for every sample


def synthetic(material: str, seed: int = 0, noise: float = RELATIVE_NOISE):
    """Goniometer-like measurements of a paper-003 Table-1 material, phi >= 90 as the paper fitted."""
    truth = load_material(material)
    data = synthesize_measurements(truth.model, truth.params, *ANGLES, relative_noise=noise, seed=seed)
    return truth, filter_measurements(data, min_phi=90)


@pytest.fixture(scope="module")
def roof_tile_fit():
    truth, data = synthetic("roof_tile", seed=1)
    return truth, data, fit_measurements("torrance_sparrow", data, fixed=PAPER_K)


# --- closed forms ------------------------------------------------------------------------------


def test_lambertian_fit_is_the_weighted_mean():
    # Closed form: the weighted least-squares constant is sum(y/s^2)/sum(1/s^2), its error
    # (sum 1/s^2)^-1/2, and chi2 = sum((y - mean)^2 / s^2).
    rng = np.random.default_rng(5)
    brdf = 0.05 + 0.004 * rng.standard_normal(40)
    sigma = rng.uniform(0.002, 0.006, 40)
    theta = rng.uniform(0, 80, 40)
    result = fit_brdf("lambertian", theta, theta[::-1], rng.uniform(0, 180, 40), brdf, sigma)
    weights = 1 / sigma**2
    mean = np.sum(weights * brdf) / np.sum(weights)
    assert result.params["t0"] == pytest.approx(mean, rel=1e-9)
    assert result.errors["t0"] == pytest.approx(np.sum(weights) ** -0.5, rel=1e-6)
    assert result.chi2 == pytest.approx(np.sum(weights * (brdf - mean) ** 2), rel=1e-9)
    assert result.dof == 39
    assert result.reduced_chi2 == pytest.approx(result.chi2 / 39)
    assert not result.errors_scaled


def test_linear_subproblem_matches_weighted_linear_regression():
    # With w, n, k fixed the TS model is linear in t0, t1: f = t0 + t1 S. Closed form:
    # p = (A^T W A)^-1 A^T W y, cov = (A^T W A)^-1 (Press et al., Numerical Recipes 15.4).
    truth, data = synthetic("red_concrete", seed=3)
    fixed = {name: truth.params[name] for name in ("w", "n", "k")}
    result = fit_measurements("torrance_sparrow", data, fixed=fixed)
    shape = get_model("torrance_sparrow").kernel(data.geometry, t0=0.0, t1=1.0, **fixed)
    design = np.column_stack([np.ones_like(shape), shape]) / data.sigma[:, None]
    normal = design.T @ design
    expected = np.linalg.solve(normal, design.T @ (data.brdf / data.sigma))
    covariance = np.linalg.inv(normal)
    assert [result.params["t0"], result.params["t1"]] == pytest.approx(expected, rel=1e-6)
    np.testing.assert_allclose(result.covariance, covariance, rtol=1e-4)
    assert result.free == ("t0", "t1")
    assert result.errors["w"] == 0.0 and result.params["w"] == truth.params["w"]


def _fixed_shape_design(data, fixed):
    shape = get_model("torrance_sparrow").kernel(data.geometry, t0=0.0, t1=1.0, **fixed)
    return np.column_stack([np.ones_like(shape), shape])


def test_unweighted_errors_are_the_hc3_sandwich_or_scaled_on_request():
    # Linear in t0, t1 with the shape fixed: the residuals and the design give the covariances in
    # closed form. Default without sigma: HC3, B (X^T diag(r^2 / (1 - h)^2) X) B, B = (X^T X)^-1
    # (MacKinnon and White 1985); scale_errors=True: s^2 B with s^2 = SSR / dof (Numerical Recipes
    # 15.4.2, scipy's curve_fit(absolute_sigma=False)); False: B (sigma = 1 sr^-1).
    truth, data = synthetic("blue_concrete", seed=4)
    fixed = {name: truth.params[name] for name in ("w", "n", "k")}
    result = fit_brdf("torrance_sparrow", data.theta_i, data.theta_r, data.phi, data.brdf, fixed=fixed)
    design = _fixed_shape_design(data, fixed)
    solution, ssr, *_ = np.linalg.lstsq(design, data.brdf, rcond=None)
    bread = np.linalg.inv(design.T @ design)
    residuals = data.brdf - design @ solution
    leverage = np.einsum("ij,jk,ik->i", design, bread, design)
    hc3 = bread @ (design.T * (residuals**2 / (1 - leverage) ** 2)) @ design @ bread
    assert result.errors_robust and not result.errors_scaled
    assert result.chi2 == pytest.approx(ssr[0], rel=1e-6)
    np.testing.assert_allclose(result.covariance, hc3, rtol=1e-4)
    scaled = fit_brdf("torrance_sparrow", data.theta_i, data.theta_r, data.phi, data.brdf, fixed=fixed,
                      error_analysis=ErrorAnalysis(scale_errors=True))
    assert scaled.errors_scaled and not scaled.errors_robust
    np.testing.assert_allclose(scaled.covariance, bread * ssr[0] / (data.brdf.size - 2), rtol=1e-4)
    # Scaling switched off: the errors assume sigma = 1 sr^-1, far larger than the values, which
    # the fit reports as parameters it cannot determine.
    with pytest.warns(NonIdentifiableWarning, match="not determined"):
        unscaled = fit_brdf(
            "torrance_sparrow", data.theta_i, data.theta_r, data.phi, data.brdf, fixed=fixed,
            error_analysis=ErrorAnalysis(scale_errors=False),
        )
    np.testing.assert_allclose(unscaled.covariance, bread, rtol=1e-4)


def test_unweighted_errors_match_the_spread_of_relative_noise():
    # Goniometer noise is relative (paper 003: 4-15 % of the value) and the roof tile's BRDF spans
    # 17x in the fitted half: the errors scaled by chi2/dof assume equal noise and are ~0.7x the
    # spread of the fitted values over noise draws, the robust ones match it. Monte Carlo: 200
    # draws, t0 and t1 free (the shape fixed at the truth: linear, so each fit is fast).
    truth = load_material("roof_tile")
    fixed = {name: truth.params[name] for name in ("w", "n", "k")}
    _, data = synthetic("roof_tile", noise=0.0)
    rng = np.random.default_rng(11)
    fits, reported = [], []
    for _ in range(200):
        noisy = data.brdf * (1 + RELATIVE_NOISE * rng.standard_normal(data.brdf.size))
        result = fit_brdf("torrance_sparrow", data.theta_i, data.theta_r, data.phi, noisy, fixed=fixed)
        fits.append([result.params["t0"], result.params["t1"]])
        reported.append([result.errors["t0"], result.errors["t1"]])
    ratio = np.mean(reported, axis=0) / np.std(fits, axis=0, ddof=1)
    # The sampling error of a standard deviation from 200 draws is 5 %; HC3 leans conservative.
    assert np.all((ratio > 0.85) & (ratio < 1.25)), ratio


def test_nonlinear_fit_agrees_with_curve_fit(roof_tile_fit):
    # An independent optimizer (Levenberg-Marquardt in scipy's curve_fit, started at the truth)
    # must find the same minimum and the same covariance (absolute_sigma: not scaled).
    truth, data, result = roof_tile_fit
    model = get_model("torrance_sparrow")

    def function(_, t0, t1, w, n):
        return model.kernel(data.geometry, t0=t0, t1=t1, w=w, n=n, k=0.25)

    start = [truth.params[name] for name in ("t0", "t1", "w", "n")]
    values, covariance = curve_fit(
        function, None, data.brdf, p0=start, sigma=data.sigma, absolute_sigma=True
    )
    assert [result.params[name] for name in result.free] == pytest.approx(values, rel=1e-4)
    np.testing.assert_allclose(result.covariance, covariance, rtol=2e-3)


def test_a_fit_from_one_start_is_one_local_optimization_to_the_same_minimum(roof_tile_fit):
    # choose_model's folds start from the fit to all the measurements: from the truth, the one
    # start reaches the minimum the 15 starts of fit_brdf find (Levenberg-Marquardt agrees above).
    truth, data, result = roof_tile_fit
    start = {name: truth.params[name] for name in ("t0", "t1", "w", "n")}
    single = fit_from("torrance_sparrow", data.theta_i, data.theta_r, data.phi, data.brdf, data.sigma,
                      start=start, fixed=PAPER_K)
    assert (single.n_starts, result.n_starts) == (1, 15)
    assert [single.params[name] for name in single.free] == pytest.approx(
        [result.params[name] for name in result.free], rel=1e-6)
    np.testing.assert_allclose(single.covariance, result.covariance, rtol=1e-4)


# --- round trips with the materials of paper 003, Table 1 --------------------------------------


def test_round_trip_pulls_and_chi2_over_seeds():
    """Measurements synthesized from Table 1 at goniometer angles with 4 % noise, fitted back with
    k = 0.25: the pulls (fit - truth) / error must look like N(0, 1) and chi2 like chi2(dof)."""
    pulls, reduced = [], []
    for material in ("roof_tile", "red_concrete", "blue_concrete", "red_aluminium"):
        for seed in range(6):
            truth, data = synthetic(material, seed=100 + seed)
            result = fit_measurements("torrance_sparrow", data, fixed=PAPER_K)
            assert result.dof == len(data) - 4 == 116
            low, high = chi2_distribution.ppf([0.001, 0.999], result.dof)
            assert low < result.chi2 < high, (material, seed, result.chi2)
            assert result.params["k"] == 0.25 and result.errors["k"] == 0.0
            pulls.append([(result.params[p] - truth.params[p]) / result.errors[p] for p in result.free])
            reduced.append(result.reduced_chi2)
    pulls = np.array(pulls)
    # 96 pulls: none beyond 4 sigma (P = 6e-5 each for a normal variable) ...
    assert np.all(np.abs(pulls) < 4.0)
    # ... mean and spread of a standard normal within ~3 standard errors.
    assert abs(pulls.mean()) < 0.3
    assert 0.7 < pulls.std() < 1.3
    # Mean of 24 chi2/dof: expectation 1, standard error sqrt(2/116/24) = 0.027.
    assert np.mean(reduced) == pytest.approx(1.0, abs=0.1)


def test_fit_reproduces_truth_without_noise():
    # Noise-free data must be fitted back to the generating parameters (global minimum found).
    for material in ("roof_tile", "red_aluminium", "spectralon_50"):
        truth = load_material(material)
        geometry = ScatteringGeometry(*ANGLES)
        brdf = truth.model.evaluate(geometry, **truth.params)
        result = fit_brdf("torrance_sparrow", *ANGLES, brdf, fixed=PAPER_K)
        for name in result.free:
            assert result.params[name] == pytest.approx(truth.params[name], rel=1e-5), (material, name)


def test_simplified_and_empirical_models_fit(roof_tile_fit):
    truth, data, _ = roof_tile_fit
    simplified = fit_measurements("torrance_sparrow_simplified", data, fixed=PAPER_K)
    # Paper 003, section 5: G = 1 changes this roof tile BRDF by at most ~10 % up to 70 deg
    # zenith, so the simplified fit still describes 4 %-noise data acceptably.
    assert simplified.reduced_chi2 < 2.0
    assert simplified.params["w"] == pytest.approx(truth.params["w"], rel=0.05)
    empirical = fit_measurements("empirical", data)
    assert empirical.free == ("a", "b", "c", "t0")
    assert np.isfinite(empirical.chi2) and empirical.dof == len(data) - 4


def test_result_attributes(roof_tile_fit):
    _, data, result = roof_tile_fit
    assert list(result.params) == ["t0", "t1", "w", "n", "k"]
    assert result.fixed == {"k": 0.25}
    assert result.covariance.shape == result.correlation.shape == (4, 4)
    np.testing.assert_allclose(np.diag(result.correlation), 1.0)
    np.testing.assert_allclose(result.correlation, result.correlation.T)
    np.testing.assert_allclose(
        [result.errors[name] for name in result.free], np.sqrt(np.diag(result.covariance))
    )
    model = result.predict(data.theta_i, data.theta_r, data.phi)
    np.testing.assert_allclose(result.residuals, data.brdf - model, rtol=1e-10, atol=1e-15)
    assert result.chi2 == pytest.approx(np.sum(result.pulls**2))
    assert result.p_value == pytest.approx(chi2_distribution.sf(result.chi2, result.dof), rel=1e-12)
    assert 1 <= result.n_converged <= result.n_starts


def test_table_entry_round_trips_through_parameter_table(roof_tile_fit, tmp_path):
    _, _, result = roof_tile_fit
    path = ParameterTable().with_class(result.table_entry(1, "roof_tile")).save(tmp_path / "p.yaml")
    entry = ParameterTable.load(path)[1]
    assert entry.model == "torrance_sparrow" and entry.name == "roof_tile"
    assert entry.params == result.params  # plain floats survive YAML exactly


# --- identifiability ---------------------------------------------------------------------------


@pytest.mark.parametrize("seed", [1, 11])  # seed 1: k, n, t1 entangled; seed 11: k runs to 0
def test_free_k_trades_off_with_n_and_t1(seed):
    # Paper 003, section 4 and fig. 1: n, k and t1 cannot be retrieved simultaneously. Either the
    # three are almost linear combinations of each other, or the fit runs to k ~ 0 where the
    # Fresnel term does not depend on k: both must be reported.
    _, data = synthetic("roof_tile", seed=seed)
    with pytest.warns(NonIdentifiableWarning, match="not identifiable") as caught:
        result = fit_measurements("torrance_sparrow", data)
    assert "k" in str(caught[0].message)
    assert result.global_correlation["k"] > 0.99 or result.errors["k"] > 0.25
    assert len(result.warnings) >= 1


def test_no_identifiability_warning_with_k_fixed(roof_tile_fit):
    _, data, _ = roof_tile_fit
    with warnings.catch_warnings():
        warnings.simplefilter("error", FitWarning)
        result = fit_measurements("torrance_sparrow", data, fixed=PAPER_K)
    assert result.warnings == ()
    assert np.all(np.abs(result.correlation[np.triu_indices(4, 1)]) < 0.99)
    assert max(result.global_correlation.values()) < 0.99


def test_parameter_without_effect_gives_infinite_errors(roof_tile_fit):
    # With the peak intensity a fixed at 0, b and c do not change the model: singular Jacobian.
    _, data, _ = roof_tile_fit
    with pytest.warns(NonIdentifiableWarning, match="singular"):
        result = fit_measurements("empirical", data, fixed={"a": 0.0})
    assert np.isinf(result.errors["b"]) and np.isinf(result.errors["c"])


def test_parameter_on_a_bound_warns(roof_tile_fit):
    truth, data, _ = roof_tile_fit
    with pytest.warns(FitWarning, match="bound"):
        result = fit_measurements("torrance_sparrow", data, fixed=PAPER_K, bounds={"w": (0.05, 0.2)})
    assert result.params["w"] == pytest.approx(0.05)
    assert result.at_bounds == ("w",)


# --- starting values ---------------------------------------------------------------------------


def test_a_failing_start_is_rescued_by_the_start_grid():
    # From w = 0.003 deg^-1 (a peak 50 times too wide) with the peak switched off (t1 = 0, where
    # the gradient with respect to w and n vanishes) a single least-squares run on the aluminium
    # sample does not find the peak (checked directly with scipy); fit_brdf tries that start
    # first and then its grid, and must end at the same minimum as without the bad guess.
    truth, data = synthetic("red_aluminium", seed=1)
    model = get_model("torrance_sparrow")

    def residuals(x):
        return (model.kernel(data.geometry, *x, k=0.25) - data.brdf) / data.sigma

    bad_start = [0.0109, 0.0, 0.003, 1.5]
    single = least_squares(
        residuals, bad_start, bounds=([0, 0, 1e-6, 1e-6], np.inf), x_scale="jac", method="trf"
    )
    reference = fit_measurements("torrance_sparrow", data, fixed=PAPER_K)
    assert 2 * single.cost > 10 * reference.chi2
    rescued = fit_measurements(
        "torrance_sparrow", data, fixed=PAPER_K, initial=dict(zip(("t0", "t1", "w", "n"), bad_start))
    )
    assert rescued.chi2 == pytest.approx(reference.chi2, rel=1e-6)
    assert rescued.n_starts == reference.n_starts + 1
    assert rescued.n_converged < rescued.n_starts


# --- bad input -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"fixed": {"q": 1.0}}, ParameterError, "unknown parameter 'q'"),
        ({"fixed": {"w": -1.0}}, ParameterError, "w = -1"),
        ({"fixed": {"k": 0.25}, "initial": {"k": 0.3}}, ParameterError, "fixed and cannot"),
        ({"bounds": {"w": (0.5, 0.1)}}, ParameterError, "bounds of w"),
        ({"bounds": {"w": 0.5}}, ParameterError, "must be a pair"),
        ({"initial": {"n": 0.0}}, ParameterError, "starting value n"),
        ({"initial": {"n": "high"}}, ParameterError, "starting value of n must be a single number"),
        ({"initial": {"n": float("nan")}}, ParameterError, "starting value of n must be finite"),
        ({"fixed": {"k": [0.1, 0.2]}}, ParameterError, "fixed value of k must be a single number"),
        ({"fixed": {"t0": 0.1, "t1": 0.1, "w": 0.1, "n": 1.5, "k": 0.2}}, FitError, "nothing to fit"),
    ],
)
def test_bad_parameters(roof_tile_fit, kwargs, error, match):
    _, data, _ = roof_tile_fit
    with pytest.raises(error, match=match):
        fit_measurements("torrance_sparrow", data, **kwargs)


def test_a_start_outside_the_physical_range_names_that_range_not_the_optimizers_floor(roof_tile_fit):
    # The optimizer needs closed bounds: w > 0 becomes w >= OPEN_BOUND_FLOOR * default (5e-08); the
    # message named that floor as the bound ("outside its bounds [5e-08, inf]"), and refused a start
    # of 1e-12, which is physically valid.
    from brdfcorr.fit.goniometer import OPEN_BOUND_FLOOR

    _, data, reference = roof_tile_fit
    floor = OPEN_BOUND_FLOOR * get_model("torrance_sparrow").parameter("w").default
    for start in (0.0, -1.0):
        with pytest.raises(ParameterError, match=r"starting value w = -?\d+ is outside its physical range w > 0 ") as caught:
            fit_measurements("torrance_sparrow", data, fixed=PAPER_K, initial={"w": start})
        assert f"{floor:g}" not in str(caught.value)
    with pytest.raises(ParameterError, match=r"starting value w = 2 is outside its bounds \[0, 1\]$"):
        fit_measurements("torrance_sparrow", data, fixed=PAPER_K, initial={"w": 2.0}, bounds={"w": (0.0, 1.0)})
    # Between the open bound and the floor: a valid start, tried from the floor.
    tiny = fit_measurements("torrance_sparrow", data, fixed=PAPER_K, initial={"w": 1e-12})
    assert tiny.chi2 == pytest.approx(reference.chi2, rel=1e-6)
    # Bounds that leave room only below the floor say so instead of "no room within w > 0".
    with pytest.raises(ParameterError, match=rf"leave no room above {floor:g}, the least value a fit takes"):
        fit_measurements("torrance_sparrow", data, fixed=PAPER_K, bounds={"w": (0.0, 1e-9)})


def test_bad_measurement_arrays_name_the_index():
    with pytest.raises(MeasurementError, match=r"brdf is NaN or infinite at index 1"):
        fit_brdf("lambertian", [10, 20, 30], [10, 20, 30], [180, 180, 180], [0.1, np.nan, 0.1])
    with pytest.raises(MeasurementError, match=r"theta_i outside \[0, 90\) deg at index 2"):
        fit_brdf("lambertian", [10, 20, 90], [10, 20, 30], [180, 180, 180], [0.1, 0.1, 0.1])
    with pytest.raises(MeasurementError, match="different shapes"):
        fit_brdf("lambertian", [10, 20], [10, 20, 30], [180, 180, 180], [0.1, 0.1, 0.1])


def test_too_few_measurements():
    with pytest.raises(FitError, match="at least 5 are needed"):
        fit_brdf("torrance_sparrow", [30] * 4, [10, 20, 30, 40], [180] * 4, [0.1] * 4, fixed=PAPER_K)


def test_unknown_model_is_a_brdfcorr_error():
    with pytest.raises(BrdfcorrError, match="unknown BRDF model"):
        fit_brdf("phong", [30, 40], [30, 40], [180, 180], [0.1, 0.1])


# --- formatting ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("value", "error", "text"),
    [
        # paper 003, Table 1 (roof tile, red concrete): one digit unless the error starts with 1-2
        (0.0245, 0.0003, "0.0245 ± 0.0003"),
        (0.20, 0.05, "0.20 ± 0.05"),
        (0.0362, 0.0004, "0.0362 ± 0.0004"),
        (1.48, 0.11, "1.48 ± 0.11"),
        (1.77, 0.3, "1.8 ± 0.3"),
        (1.06, 0.2, "1.06 ± 0.20"),
        (123.4, 12.0, "123 ± 12"),
        (1.234, 0.0096, "1.23 ± 0.01"),
    ],
)
def test_format_with_error(value, error, text):
    assert format_with_error(value, error) == text


# --- array kinds -------------------------------------------------------------------------------


def test_xarray_and_list_inputs_give_the_numpy_result(roof_tile_fit):
    import xarray as xr

    _, data, reference = roof_tile_fit
    arrays = [
        xr.DataArray(values, dims="measurement")
        for values in (data.theta_i, data.theta_r, data.phi, data.brdf, data.sigma)
    ]
    result = fit_brdf("torrance_sparrow", *arrays, fixed=PAPER_K)
    assert result.params == pytest.approx(reference.params, rel=1e-9)
    listed = fit_brdf("torrance_sparrow", *(list(a.values) for a in arrays), fixed=PAPER_K)
    assert listed.chi2 == pytest.approx(reference.chi2, rel=1e-12)


# --- figures -----------------------------------------------------------------------------------


def test_figures_have_one_panel_per_scan(roof_tile_fit):
    from brdfcorr.plot.fits import azimuth_cuts, plot_azimuth, plot_principal_plane, principal_plane_cuts

    truth, data, result = roof_tile_fit
    everything = synthesize_measurements(truth.model, truth.params, *ANGLES, seed=1)
    excluded = everything.select(everything.phi < 90, "phi < 90")
    # The goniometer grid: principal-plane scans at 30, 50, 65 deg; azimuth scans at 4 zenith pairs.
    assert principal_plane_cuts(data) == [30.0, 50.0, 65.0]
    assert azimuth_cuts(data) == [(30.0, 30.0), (50.0, 50.0), (65.0, 50.0), (65.0, 70.0)]
    figure = plot_principal_plane(result, data, excluded)
    panels = [axis for axis in figure.axes if axis.get_visible()]
    assert len(panels) == 3
    # Every fitted in-plane measurement is drawn with an error bar: 16 forward points at 30 deg.
    containers = panels[0].containers
    assert len(containers[0].lines[0].get_xdata()) == 16
    # Not fitted: the 15 backward points (5..75 deg, phi = 0) and phi = 0 of the (30, 30) scan.
    assert len(containers[1].lines[0].get_xdata()) == 16
    figure = plot_azimuth(result, data, excluded, yscale="log")
    panels = [axis for axis in figure.axes if axis.get_visible()]
    assert len(panels) == 5  # 4 cuts + the normalized specular part, as paper 003 fig. 3
    assert panels[0].get_yscale() == "log"


def test_figure_titles_count_the_measurements_they_show(roof_tile_fit):
    # The principal-plane figure shows only the measurements within the azimuth tolerance of
    # phi = 0/180 (or at nadir); its title counted every fitted one (120, of which 48 are in-plane).
    from brdfcorr.plot.fits import plot_azimuth, plot_principal_plane

    _, data, result = roof_tile_fit
    in_plane = (np.abs(data.phi - 180.0) <= 0.5) | (data.phi <= 0.5) | (data.theta_r <= 0.5)
    assert 0 < np.count_nonzero(in_plane) < len(data)
    title = plot_principal_plane(result, data)._suptitle.get_text()
    assert f"{np.count_nonzero(in_plane)} of {len(data)} fitted measurements" in title
    # A wider tolerance takes in the azimuth scans' points near phi = 180 as well.
    wide = (np.abs(data.phi - 180.0) <= 20.0) | (data.phi <= 20.0) | (data.theta_r <= 20.0)
    assert np.count_nonzero(wide) > np.count_nonzero(in_plane)
    title = plot_principal_plane(result, data, tolerance=20.0)._suptitle.get_text()
    assert f"{np.count_nonzero(wide)} of {len(data)} fitted measurements" in title
    # The azimuth figure counts the measurements of its cuts (theta_r > 0 pairs with 4+ azimuths).
    pairs = np.round(np.column_stack([data.theta_i, data.theta_r]), 1)
    on_cuts = sum(np.count_nonzero(np.all(pairs == cut, axis=1))
                  for cut in [(30.0, 30.0), (50.0, 50.0), (65.0, 50.0), (65.0, 70.0)])
    assert f"{on_cuts} of {len(data)} fitted measurements" in plot_azimuth(result, data)._suptitle.get_text()


# --- energy conservation -----------------------------------------------------------------------


@pytest.mark.parametrize(("level", "warns"), [(0.30, False), (0.33, True), (0.5, True)])
def test_a_fit_whose_albedo_exceeds_one_warns(level, warns):
    # Closed form: a Lambertian BRDF t0 has albedo pi * t0 at every zenith, > 1 from t0 > 1/pi.
    from brdfcorr.fit.goniometer import AlbedoWarning

    rng = np.random.default_rng(2)
    theta_i, theta_r, phi = rng.uniform(0, 70, 30), rng.uniform(0, 70, 30), rng.uniform(0, 180, 30)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fit_brdf("lambertian", theta_i, theta_r, phi, np.full(30, level) * (1 + 0.01 * rng.standard_normal(30)))
    albedo = [w for w in caught if issubclass(w.category, AlbedoWarning)]
    assert len(albedo) == int(warns)
    if warns:
        message = str(albedo[0].message)
        assert f"albedo (its integral of BRDF cos(theta_r) over the hemisphere) {np.pi * result.params['t0']:.3g} > 1" in message
        assert f"divided by pi the albedo is {result.params['t0']:.3g}" in message and "percent" in message
        assert issubclass(AlbedoWarning, FitWarning)
        assert message not in result.warnings  # it says nothing about the errors


def test_measurements_in_percent_warn_and_brdf_does_not(roof_tile_fit):
    from brdfcorr.fit.goniometer import AlbedoWarning
    from brdfcorr.fit.measurements import Measurements

    _, data, _ = roof_tile_fit
    with warnings.catch_warnings():
        warnings.simplefilter("error", AlbedoWarning)
        fit_measurements("torrance_sparrow", data, fixed=PAPER_K)  # the roof tile's albedo is about 0.14
    percent = Measurements(data.theta_i, data.theta_r, data.phi, 100 * data.brdf, 100 * data.sigma)
    with pytest.warns(AlbedoWarning, match=r"albedo .* > 1 at theta_i = 65 deg.* in percent \(divided by 100: 0\.1"):
        fit_measurements("torrance_sparrow", percent, fixed=PAPER_K)


# --- several wavelengths -----------------------------------------------------------------------


def spectral_measurements():
    """Roof tile at three wavelengths: t0 varies with wavelength (a red tile), the peak does not."""
    truth = load_material("roof_tile")
    t0 = {450.0: 0.015, 550.0: truth.params["t0"], 650.0: 0.045}
    parts = [
        synthesize_measurements(
            truth.model, {**truth.params, "t0": value}, *ANGLES, seed=index, wavelength=wavelength
        )
        for index, (wavelength, value) in enumerate(t0.items())
    ]
    columns = {
        name: np.concatenate([getattr(part, name) for part in parts])
        for name in ("theta_i", "theta_r", "phi", "brdf", "sigma", "wavelength")
    }
    from brdfcorr.fit.measurements import Measurements

    return t0, filter_measurements(Measurements(**columns), min_phi=90)


def test_fit_wavelengths_and_spectral_table_entry(tmp_path):
    from brdfcorr.fit.goniometer import fit_wavelengths, spectral_table_entry

    t0, data = spectral_measurements()
    results = fit_wavelengths("torrance_sparrow", data, fixed=PAPER_K)
    assert list(results) == [450.0, 550.0, 650.0]
    for wavelength, result in results.items():
        assert result.n_measurements == 120
        assert abs(result.params["t0"] - t0[wavelength]) < 4 * result.errors["t0"]
    entry = spectral_table_entry(results, 4, "red_tile")
    assert entry["wavelengths"] == [450.0, 550.0, 650.0]
    assert entry["params"]["k"] == 0.25  # fixed: one scalar for every wavelength
    path = ParameterTable().with_class(entry).save(tmp_path / "spectral.yaml")
    table = ParameterTable.load(path)
    # The correction code gets each fit back at its own wavelength and the linear interpolation
    # between them elsewhere.
    at_nodes = table.for_bands(wavelengths=[450.0, 550.0, 650.0])[4].params
    for index, result in enumerate(results.values()):
        for name in ("t0", "t1", "w", "n"):
            assert at_nodes[name][index] == result.params[name]
    between = table.for_bands(wavelengths=[500.0])[4].params["t0"][0]
    assert between == pytest.approx(0.5 * (results[450.0].params["t0"] + results[550.0].params["t0"]))
    # One wavelength: the paper-003 practice, scalars for every band.
    single = spectral_table_entry({550.0: results[550.0]}, 1, "tile")
    assert "wavelengths" not in single and single["params"] == results[550.0].params


def test_fit_wavelengths_needs_a_wavelength_column(roof_tile_fit):
    from brdfcorr.fit.goniometer import fit_wavelengths

    _, data, _ = roof_tile_fit
    with pytest.raises(FitError, match="no wavelength column"):
        fit_wavelengths("torrance_sparrow", data)


@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_the_jacobians_batched_evaluations_are_the_single_ones_value_for_value(name):
    # least_squares evaluates a finite-difference Jacobian's points through `workers`: the batched
    # evaluation (one model call over every point) must give each point's residuals exactly as
    # the one-point function does, or the fits would depend on how the points were grouped.
    model = get_model(name)
    rng = np.random.default_rng(5)
    theta_i, theta_r, phi = goniometer_angles()
    defaults = {parameter.name: parameter.default for parameter in model.parameters}
    brdf = model(theta_i, theta_r, phi, **defaults) * (1 + 0.05 * rng.standard_normal(theta_i.size))
    problem, _, _ = _problem(model, (theta_i, theta_r, phi, brdf, None), None, None, None)
    low, high = np.clip(problem.lower, -5, 5), np.clip(problem.upper, -5, 5)
    points = [low + (high - low) * rng.uniform(0.05, 0.95, low.size) for _ in range(6)]
    rows = problem.residual_rows(None, iter(points))
    assert rows.shape == (len(points), brdf.size)
    for point, row in zip(points, rows):
        np.testing.assert_array_equal(row, problem.weighted_residuals(point))


def test_a_bound_that_leaves_out_the_default_starts_inside_it():
    # The empirical model's b has the range (-inf, 10] and the default 1: bounds (-inf, -0.5) or
    # (-1e308, -0.5) once started the fit at the midpoint (-inf: no start converged; -5e307: a
    # nonsense fit). Whatever the far end, the fit is the one with a finite far end (b = -0.5
    # here, the bound: the roof tile's peak wants b > 0).
    _, data = synthetic("roof_tile", seed=2)
    args = ("empirical", data.theta_i, data.theta_r, data.phi, data.brdf, data.sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        reference = fit_brdf(*args, bounds={"b": (-100.0, -0.5)})
        for low in (-np.inf, -1e308):
            result = fit_brdf(*args, bounds={"b": (low, -0.5)})
            assert result.params["b"] == pytest.approx(reference.params["b"], abs=1e-9)
            assert result.chi2 == pytest.approx(reference.chi2, rel=1e-9)


def test_a_nan_bound_is_refused():
    _, data = synthetic("roof_tile", seed=2)
    for pair in ((np.nan, 0.1), (0.01, np.nan)):
        with pytest.raises(ParameterError, match="bounds of w must be numbers"):
            fit_brdf("torrance_sparrow", data.theta_i, data.theta_r, data.phi, data.brdf, data.sigma,
                     fixed=PAPER_K, bounds={"w": pair})


def test_the_paper_003_hint_is_for_the_torrance_sparrow_k_only():
    # RPV's k is the Minnaert-like exponent, not the absorption index paper 003 fixes at 0.25.
    covariance = np.array([[1.0, 0.9999], [0.9999, 1.0]])
    values = {"k": 0.5, "n": 1.0, "rho0": 0.05}
    hints = {name: identifiability_messages(get_model(name), ("k", other), values, covariance, 1e3, 0.99)
             for name, other in (("torrance_sparrow", "n"), ("rpv", "rho0"))}
    assert "paper 003 fixes k = 0.25" in hints["torrance_sparrow"][0]
    assert "trade off" in hints["rpv"][0] and "paper 003" not in hints["rpv"][0]


def test_without_sigma_another_minimum_counts_within_one_residual_variance():
    # Without sigmas chi^2 is a sum of squares [sr^-2]: the reach max(1, chi2/dof) = 1 sr^-2 took a
    # minimum with 5.8 times the best's sum of squares (1464 residual variances worse) for as good,
    # and flagged the errors of a fit whose weighted twin is reliable.
    ti, tr, phi = goniometer_angles(theta_i=(10.0, 30.0, 50.0, 65.0, 75.0), max_view=80)
    data = synthesize_measurements("torrance_sparrow", load_material("roof_tile").params, ti, tr, phi,
                                   relative_noise=0.04, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bare = fit_brdf("torrance_sparrow", ti, tr, phi, data.brdf, None, fixed=PAPER_K)
        weighted = fit_brdf("torrance_sparrow", ti, tr, phi, data.brdf, data.sigma, fixed=PAPER_K)
    assert weighted.errors_reliable and bare.errors_reliable
    assert not any("another minimum" in message for message in bare.warnings)


def test_another_minimum_as_good_far_outside_the_errors_is_named():
    # The roof tile's backscatter half alone: starts ending at n = 0.01 and n = 4.4 fit alike
    # (chi2 37.93 and 37.95), and the errors of the one kept (n 0.01 +- 0.05) put the other 80
    # errors away, without a warning. A start's minimum counts where its chi2 is within
    # max(1, chi2/dof) of the best (cost = chi2 / 2).
    from types import SimpleNamespace

    from brdfcorr.fit.identifiability import identifiability_messages, other_minima

    free = ["t0", "t1", "w", "n"]
    best = SimpleNamespace(x=np.array([0.0249, 0.018, 0.0379, 0.01]), cost=37.93 / 2)
    twin = SimpleNamespace(x=np.array([0.0249, 0.068, 0.0379, 4.39]), cost=37.95 / 2)
    worse = SimpleNamespace(x=np.array([0.03, 1.1, 0.04, 1.0]), cost=41.0 / 2)
    others = other_minima(best, [best, twin, worse], 37.93 / 44)
    assert [tuple(x) for x in others] == [tuple(twin.x)]
    values = dict(zip(free, best.x))
    covariance = np.diag([0.00022, 0.003, 0.0012, 0.05]) ** 2
    messages = identifiability_messages(get_model("torrance_sparrow"), free, values, covariance, 10.0, 0.99, others)
    assert len(messages) == 1 and "another minimum fits as well at n = 4.39, 88 errors from 0.01" in messages[0]
    # A minimum within the errors is the same one.
    close = [np.array([0.0249, 0.018, 0.0379, 0.05])]
    assert identifiability_messages(get_model("torrance_sparrow"), free, values, covariance, 10.0, 0.99, close) == []
