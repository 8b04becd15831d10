"""Class fits of models without free shape parameters (kernel-driven): one linear least-squares
pass, calibrated errors, non-negativity, and the fit-quality guard rail with its model suggestion."""

import math
import warnings

import numpy as np
import pytest
import scipy.optimize

from brdfcorr.fit import classes, shape_search, solver
from brdfcorr.fit import profile as profiles
from brdfcorr.fit.classes import ClassFitWarning, ClassSamples, GuardRails, fit_one_class
from brdfcorr.fit.quality import fit_quality
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import Model, Parameter, get_model, torrance_sparrow
from brdfcorr.models.kernels import KERNEL_DRIVEN_MODELS

RTLSR = get_model("ross_thick_li_sparse")
#: Per band (4 bands) kernel weights [sr^-1] of a vegetated class: backscatter brighter than forward.
TRUTH = {
    "f_iso": np.array([0.012, 0.025, 0.018, 0.11]),
    "f_vol": np.array([0.006, 0.012, 0.007, 0.06]),
    "f_geo": np.array([0.002, 0.004, 0.003, 0.015]),
}


def airborne_lines(n, seed, headings=(5.0, 50.0, 95.0)):
    """Sun and view angles [deg] of ``n`` pixels from flight lines at the given headings relative
    to the sun azimuth: sun zenith 30-50 deg, view zenith up to 40 deg on either side."""
    rng = np.random.default_rng(seed)
    heading = rng.choice(headings, n)
    across = rng.uniform(-1, 1, n)
    vaa = np.where(across < 0, heading - 90.0, heading + 90.0) % 360
    return rng.uniform(30, 50, n), 40.0 * np.abs(across), relative_azimuth(np.zeros(n), vaa)


def render(angles, truth=TRUTH, model=RTLSR):
    return model(*(a[:, None] for a in angles), **truth)


@pytest.fixture
def one_pass_only(monkeypatch):
    """Count the design evaluations and linear solves; fail on any search or Newton step."""
    calls = {"design": 0, "solve": 0}
    for name in ("design", "solve"):
        original = getattr(profiles._LinearProfile, name)

        def counted(self, *args, _original=original, _name=name):
            calls[_name] += 1
            return _original(self, *args)

        monkeypatch.setattr(profiles._LinearProfile, name, counted)
    for name in ("_search", "_refine", "_newton_polish", "_grid_start", "_coarse_shape"):
        for module in (shape_search, solver):  # the search's module, and the solver that imports its steps
            if hasattr(module, name):
                monkeypatch.setattr(module, name, lambda *args, _name=name, **kwargs: pytest.fail(f"{_name} called"))
    return calls


def test_kernel_model_is_solved_in_one_pass_and_recovered_within_errors(one_pass_only):
    rng = np.random.default_rng(1)
    angles = airborne_lines(6000, seed=1)
    brdf = render(angles) + 0.0005 * rng.standard_normal((6000, 4))
    result = fit_class_samples(RTLSR, *angles, brdf)
    assert one_pass_only == {"design": 1, "solve": 1}
    assert result["shape"] == {} and result["at_edge"] == []
    for name, truth in TRUTH.items():
        errors = result["errors"][name]
        assert np.all(errors > 0)
        assert np.all(np.abs(result["params"][name] - truth) < 3 * errors), name


def test_exact_kernel_data_give_the_exact_coefficients():
    # Noise-free data: linear least squares reproduces the coefficients (closed form).
    angles = airborne_lines(3000, seed=2)
    result = fit_class_samples(RTLSR, *angles, render(angles))
    for name, truth in TRUTH.items():
        np.testing.assert_allclose(result["params"][name], truth, rtol=1e-10, atol=0)
    np.testing.assert_allclose(result["r2"], 1.0, atol=1e-10)


def test_kernel_errors_are_calibrated_over_seeds():
    # Additive homoscedastic noise: the pulls (fit - truth) / error over 30 noise realizations
    # (3 weights x 4 bands each) have a standard deviation near 1.
    angles = airborne_lines(2000, seed=3)
    clean = render(angles)
    pulls = []
    for seed in range(30):
        noisy = clean + 0.001 * np.random.default_rng(seed).standard_normal(clean.shape)
        result = fit_class_samples(RTLSR, *angles, noisy)
        pulls += [(result["params"][name] - truth) / result["errors"][name] for name, truth in TRUTH.items()]
    assert 0.7 <= np.std(pulls) <= 1.4
    assert abs(np.mean(pulls)) < 0.2


def test_kernel_class_fitted_with_empirical_fails_and_a_kernel_model_is_suggested():
    # Sun across track: backscatter side brighter than the forward side, which a specular-peak
    # model (a >= 0) cannot describe at all.
    rng = np.random.default_rng(4)
    n = 4000
    sza, across = rng.uniform(35, 45, n), rng.uniform(-1, 1, n)
    angles = (sza, 40 * np.abs(across), relative_azimuth(np.full(n, 95.0), np.where(across < 0, 270.0, 90.0)))
    brdf = render(angles) * (1 + 0.01 * rng.standard_normal((n, 4)))
    with pytest.warns(ClassFitWarning, match=r"empirical explains almost none.*ross_.* explains more"):
        fit = fit_one_class(7, "meadow", "empirical", ClassSamples(*angles, brdf))
    assert fit.status == "uncorrected"
    assert any("median angular R^2" in reason for reason in fit.reasons)
    assert fit.median_angular_r2 < 0.05
    assert any("at the edge of its search range" in reason for reason in fit.reasons), fit.reasons
    assert fit.median_r2 < 0.05
    kernel_models = {model.name for model in KERNEL_DRIVEN_MODELS.values()}
    assert fit.better_model in kernel_models and fit.better_r2 > 0.9
    summary = fit.summary()
    assert summary["better_model"] == fit.better_model
    assert summary["better_model_median_r2"] == pytest.approx(fit.better_r2)

    # The right model passes, with no suggestion.
    with warnings.catch_warnings():
        warnings.simplefilter("error", ClassFitWarning)
        good = fit_one_class(7, "meadow", RTLSR, ClassSamples(*angles, brdf))
    assert good.status == "fitted" and good.better_model is None and good.median_r2 > 0.9


def test_a_class_failing_only_for_its_views_tries_no_other_model(monkeypatch):
    # Too narrow a view range is the sample's fault, not the model's: the right model fits well,
    # fails the spread guard alone, and no other model is fitted (choose_class_model not called).
    rng = np.random.default_rng(4)
    n = 4000
    sza, across = rng.uniform(35, 45, n), rng.uniform(-1, 1, n)
    angles = (sza, 40 * np.abs(across), relative_azimuth(np.full(n, 95.0), np.where(across < 0, 270.0, 90.0)))
    brdf = render(angles) * (1 + 0.01 * rng.standard_normal((n, 4)))

    def no_choice(*args, **kwargs):
        raise AssertionError("another model was tried for a sample no model mends")

    monkeypatch.setattr(classes, "choose_class_model", no_choice)
    with pytest.warns(ClassFitWarning, match=r"view zenith spread"):
        fit = fit_one_class(7, "meadow", RTLSR, ClassSamples(*angles, brdf), guard=GuardRails(min_vza_spread=89.0))
    assert fit.status == "uncorrected" and fit.median_r2 > 0.9
    assert len(fit.reasons) == 1 and fit.reasons[0].startswith("view zenith spread"), fit.reasons
    assert fit.better_model is None


def test_specular_intensity_stays_non_negative_without_a_specular_peak():
    # Torrance-Sparrow data with t1 = 0 and noise: the least-squares t1 is often < 0; the fit keeps
    # it >= 0 (exactly 0 or the best non-negative value) and flags the class.
    ts_angles = airborne_lines(1500, seed=5, headings=(0.0, 90.0))
    truth = {"t0": np.array([0.02, 0.05]), "t1": 0.0, "w": 0.08, "n": 1.5, "k": 0.25}
    clean = torrance_sparrow(*(a[:, None] for a in ts_angles), **truth)
    for seed in range(5):
        noisy = clean + 0.002 * np.random.default_rng(seed).standard_normal(clean.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ClassFitWarning)
            fit = fit_one_class(1, "flat", "torrance_sparrow", ClassSamples(*ts_angles, noisy),
                                guard=GuardRails(min_samples=100))
        assert np.all(fit.params["t1"] >= 0), fit.params["t1"]
        assert np.all(fit.params["t0"] > 0)
        assert fit.status == "uncorrected" and fit.median_r2 < 0.05


def test_terms_without_a_lower_bound_may_be_negative():
    # A linear term with lower bound -inf is free: a negative truth is recovered exactly, while a
    # term with lower bound 0 is held at 0.
    def basis(geometry, **_):
        return 1.0, np.cos(np.radians(geometry.phi))

    free = Model(
        name="test_free_slope", description="", reference="",
        parameters=(Parameter("c0", "sr^-1", 0.1, 0.0), Parameter("c1", "sr^-1", 0.0, -math.inf)),
        kernel=lambda geometry, c0, c1: c0 + c1 * np.cos(np.radians(geometry.phi)),
        linear=("c0", "c1"), basis=basis,
    )
    angles = airborne_lines(500, seed=6)
    profile = profiles._LinearProfile(free, ScatteringGeometry(*angles), free.kernel(
        ScatteringGeometry(*angles), c0=0.05, c1=-0.02)[:, None], {})
    coefficients, ssr = profile.solve(profile.design({}))
    np.testing.assert_allclose(coefficients[:, 0], [0.05, -0.02], rtol=1e-10)
    assert ssr[0] == pytest.approx(0.0, abs=1e-20)
    bounded = Model(
        name="test_bounded_slope", description="", reference="",
        parameters=(Parameter("c0", "sr^-1", 0.1, 0.0), Parameter("c1", "sr^-1", 0.0, 0.0)),
        kernel=free.kernel, linear=("c0", "c1"), basis=basis,
    )
    profile = profiles._LinearProfile(bounded, profile.geometry, profile.data, {})
    coefficients, _ = profile.solve(profile.design({}))
    assert coefficients[1, 0] == 0.0 and coefficients[0, 0] == pytest.approx(profile.data.mean())


def test_the_bounded_solve_is_scipys_bounded_least_squares_band_by_band():
    # Bands whose unconstrained optimum keeps f_vol and f_geo >= 0 and bands where it does not
    # (negative truths, noise): in every band the coefficients are those of scipy's bounded linear
    # least squares (lsq_linear, an independent active-set solver) with the registry's bounds.
    rng = np.random.default_rng(11)
    angles = airborne_lines(2000, seed=11)
    truths = np.array([[0.05, 0.03, 0.01], [0.05, -0.02, 0.01], [0.05, 0.02, -0.03], [0.0, -0.01, -0.01],
                       [0.03, 0.0, 0.0], [-0.01, 0.02, 0.005]]).T
    geometry = ScatteringGeometry(*angles)
    design = np.column_stack(np.broadcast_arrays(*RTLSR.terms(geometry, {})))  # the kernels (N, 3)
    brdf = design @ truths + 0.002 * rng.standard_normal((2000, truths.shape[1]))
    profile = profiles._LinearProfile(RTLSR, geometry, brdf, {})
    np.testing.assert_allclose(profile.design({}), design)
    coefficients, ssr = profile.solve(design)
    lower = [RTLSR.parameter(name).lower for name in RTLSR.linear]
    for band in range(brdf.shape[1]):
        expected = scipy.optimize.lsq_linear(design, brdf[:, band], bounds=(lower, np.inf), tol=1e-14).x
        np.testing.assert_allclose(coefficients[:, band], expected, atol=1e-9)
        assert ssr[band] == pytest.approx(((brdf[:, band] - design @ coefficients[:, band]) ** 2).sum(), rel=1e-9)
    assert (coefficients == 0).any() and (coefficients > 0).all(axis=0).any()  # both cases were met


def test_fit_quality_of_any_weights_is_their_r2_against_a_direct_evaluation():
    # For weights other than the fit's (here the truth's halved volume weight), R^2 and RMS
    # computed from the model's own values at every sample, independently of the solver's sums.
    rng = np.random.default_rng(4)
    angles = airborne_lines(3000, seed=4)
    brdf = render(angles) * (1 + 0.05 * rng.standard_normal((3000, 1))) + 0.0005 * rng.standard_normal((3000, 4))
    weights = {**TRUTH, "f_vol": TRUTH["f_vol"] / 2}
    predicted = render(angles, weights)
    residual = ((brdf - predicted) ** 2).sum(axis=0)
    total = ((brdf - brdf.mean(axis=0)) ** 2).sum(axis=0)
    intensities = np.stack([weights[name] for name in RTLSR.linear])
    quality = fit_quality(RTLSR, *angles, brdf, intensities)
    np.testing.assert_allclose(quality["r2"], 1 - residual / total, rtol=1e-9)
    np.testing.assert_allclose(quality["rmse"], np.sqrt(residual / 3000), rtol=1e-9)
    np.testing.assert_allclose(quality["chi2_dof"], residual / (3000 - 3), rtol=1e-9)
    # At the fit's own solution, it is what the fit reported; the least-squares solution has the
    # highest R^2 of any weights.
    fit = fit_class_samples(RTLSR, *angles, brdf)
    own = fit_quality(RTLSR, *angles, brdf, np.stack([fit["params"][name] for name in RTLSR.linear]))
    for name in ("r2", "rmse", "chi2_dof", "angular_r2"):
        np.testing.assert_allclose(own[name], fit[name], rtol=1e-9)
    assert np.all(quality["r2"] < fit["r2"]) and np.all(quality["angular_r2"] < fit["angular_r2"])


def test_a_fit_outside_its_models_range_fails_the_class_instead_of_the_table(monkeypatch):
    # A degenerate fit (free levels that absorb the peak) once gave the empirical model's a = 6e25
    # sr^-1; the table refuses a > 1000 (the model's range), and fit-classes crashed with pydantic's
    # error. The class fails its guard rails instead, named, and the other classes keep their fit.
    angles = airborne_lines(2000, seed=3)
    brdf = render(angles)
    original = classes.fit_class_samples

    def overflowing(*args, **kwargs):
        result = original(*args, **kwargs)
        return {**result, "params": {**result["params"], "f_vol": np.full(4, -np.inf)}}

    monkeypatch.setattr(classes, "fit_class_samples", overflowing)
    with pytest.warns(ClassFitWarning, match=r"class 7 \(meadow\): fitted ross_thick_li_sparse: parameter f_vol"):
        fit = fit_one_class(7, "meadow", RTLSR, ClassSamples(*angles, brdf))
    assert fit.status == "uncorrected"
    assert classes.class_entry(fit, [450.0, 550.0, 650.0, 850.0], "test") is None


def test_a_class_without_angular_signal_is_told_so():
    # A uniform Lambertian class: no bin mean stands out of the scatter, the angular R^2 is undefined
    # (NaN), which the reason says instead of "median angular R^2 nan < 0.05".
    angles = airborne_lines(4000, seed=5)
    brdf = np.full((4000, 2), 0.03)
    with pytest.warns(ClassFitWarning, match="no angular signal stands out"):
        fit = fit_one_class(7, "lawn", RTLSR, ClassSamples(*angles, brdf))
    assert math.isnan(fit.median_angular_r2) and fit.status == "uncorrected"
