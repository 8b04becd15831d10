"""Small-sample corrections of the imagery fit's errors (issue 27), the errors_reliable flag, and
the uncertainty of library-material classes.

Closed forms and independent computations only; the Monte-Carlo calibration (pull SDs by scene
size) is ``benchmarks/bench_small_scene_errors.py``.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import scipy.linalg
import xarray as xr

from brdfcorr.correction.uncertainty import correction_uncertainty
from brdfcorr.errors import BrdfcorrWarning
from brdfcorr.fit.classes import fit_one_class
from brdfcorr.fit.entries import class_entry
from brdfcorr.fit.identifiability import MIN_ERROR_DOF, NONLINEAR_FRACTION, error_reliability, t_variance_factor
from brdfcorr.fit.profile import _profile
from brdfcorr.fit.sampling import ClassSamples
from brdfcorr.fit.sandwich import _joint_covariance
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import get_model, torrance_sparrow
from brdfcorr.models.materials import load_material
from brdfcorr.params import ParameterTable


def _kernel_class(n=240, groups=8, seed=3):
    """RTLSR samples with noise shared within clusters (groups of n / groups consecutive samples)."""
    rng = np.random.default_rng(seed)
    sza, vza, phi = rng.uniform(20, 50, n), rng.uniform(0, 40, n), rng.uniform(0, 180, n)
    model = get_model("ross_thick_li_sparse")
    design = np.column_stack([np.broadcast_to(np.asarray(t, float), (n,)) for t in
                              model.terms(ScatteringGeometry(sza, vza, phi), {})])
    clusters = np.arange(n) * groups // n
    shared = rng.standard_normal(groups)[clusters]
    brdf = (design @ [0.05, 0.02, 0.01]) * (1 + 0.03 * shared + 0.03 * rng.standard_normal(n))
    return model, (sza, vza, phi), design, brdf, clusters


def test_cr2_of_a_linear_model_equals_the_explicit_formula():
    # Bell and McCaffrey (2002), eq. 7, formed explicitly with n_g x n_g matrices:
    # V = (A^T A)^-1 sum_g A_g^T (I - H_gg)^-1/2 r_g r_g^T (I - H_gg)^-1/2 A_g (A^T A)^-1.
    model, angles, design, brdf, clusters = _kernel_class()
    profile = _profile(model, *angles, brdf[:, None], {})
    coefficients, _ = profile.solve(design)
    found = _joint_covariance(profile, {}, design, coefficients, clusters)
    bread = np.linalg.inv(design.T @ design)
    residuals = brdf - design @ coefficients[:, 0]
    meat = np.zeros((3, 3))
    for g in np.unique(clusters):
        rows = clusters == g
        hat = design[rows] @ bread @ design[rows].T
        adjusted = np.real(scipy.linalg.sqrtm(np.linalg.inv(np.eye(rows.sum()) - hat))) @ residuals[rows]
        score = design[rows].T @ adjusted
        meat += np.outer(score, score)
    np.testing.assert_allclose(found.covariance[0], bread @ meat @ bread, rtol=1e-8)
    # CR2 is larger than the plain CR0 sandwich (leverage < 1 only inflates the residuals).
    plain = _joint_covariance(profile, {}, design, coefficients, clusters, small_sample=False)
    assert np.all(np.diag(found.covariance[0]) > np.diag(plain.covariance[0]))


@pytest.mark.parametrize("groups", [1, 3, 6, 20])
def test_dof_of_a_mean_over_equal_clusters_is_g_minus_1(groups):
    # The Lambertian model f = t0 is a mean: with G equal clusters the Bell-McCaffrey degrees of
    # freedom are exactly G - 1 (the variance of a mean of G cluster means; none from one cluster).
    n = 12 * groups
    rng = np.random.default_rng(groups)
    angles = (np.full(n, 30.0), rng.uniform(0, 30, n), np.full(n, 90.0))
    brdf = 0.1 + 0.01 * rng.standard_normal((n, 1))
    result = fit_class_samples("lambertian", *angles, brdf, clusters=np.arange(n) % groups)
    np.testing.assert_allclose(result["error_dof"], [[groups - 1]], rtol=1e-10)
    if groups == 1:
        assert result["errors_reliable"] is False and "one block alone" in result["errors_reason"]
        return
    # The error is the CR2 one, sqrt(sum_g (sum r_g)^2 / (1 - 1/G)) / N, times the t-variance factor.
    residuals = brdf[:, 0] - brdf.mean()
    sums = np.bincount(np.arange(n) % groups, residuals)
    cr2 = np.sqrt(np.sum(sums**2) / (1 - 1 / groups)) / n
    np.testing.assert_allclose(result["errors"]["t0"][0], cr2 * np.sqrt(t_variance_factor(groups - 1)), rtol=1e-9)


def test_t_variance_factor():
    # nu / (nu - 2), the variance of Student's t; held at 2 below nu = 4.
    np.testing.assert_allclose(t_variance_factor([10.0, 6.0, 4.0, 2.5, 1.0, np.inf]),
                               [1.25, 1.5, 2.0, 2.0, 2.0, 1.0])


def test_reliability_rules():
    free, dof = ("w", "t1"), np.array([[20.0, 20.0], [20.0, 20.0]])  # (bands, parameters)
    room = {"w": np.array([0.05, 0.05]), "t1": np.array([1.0, 2.0])}
    errors = np.array([[0.001, 0.1], [0.001, 0.2]])
    assert error_reliability(free, dof, 40, 0.1, margins=(room, errors)) == (True, "")
    # The rule's edges, each on its own: dof below the minimum in one band, a block of leverage ~1,
    # an error above NONLINEAR_FRACTION of the room (band 2 of t1), a parameter at an edge or bound.
    low = dof.copy()
    low[1, 0] = MIN_ERROR_DOF - 0.1
    reliable, reason = error_reliability(free, low, 5, 0.1)
    assert not reliable and "5 spatial blocks" in reason and "w 7.9" in reason and "t1" not in reason
    assert not error_reliability(free, dof, 40, 0.995)[0]
    wide = errors.copy()
    wide[1, 1] = 1.01 * NONLINEAR_FRACTION * room["t1"][1]
    reliable, reason = error_reliability(free, dof, 40, 0.1, margins=(room, wide))
    assert not reliable and reason.startswith("t1: error 0.51 times") and "non-linear" in reason
    assert error_reliability(free, dof, 40, 0.1, at_edge=["w"])[1] == "w at the edge of its search range"
    assert error_reliability(free, dof, 40, 0.1, at_bound=["t0 = 0 in band 2"])[1] == "t0 = 0 in band 2 (at its bound)"
    # A parameter at its bound in one band (no room there) is told once, as at its bound: not as an
    # error infinitely many times its distance to the bound.
    at_zero = {"w": room["w"], "t1": np.array([0.0, 2.0])}
    reason = error_reliability(free, dof, 40, 0.1, at_bound=["t1 = 0 in band 1"], margins=(at_zero, errors))[1]
    assert reason == "t1 = 0 in band 1 (at its bound)"


def _scene(n, seed=0):
    rng = np.random.default_rng(seed)
    sza, vza = rng.uniform(25, 50, n), rng.uniform(0, 40, n)
    phi = np.where(rng.random(n) < 0.5, rng.uniform(150, 180, n), rng.uniform(0, 30, n))
    truth = {"t0": np.array([0.02, 0.06]), "t1": np.array([0.15, 0.4]), "w": 0.06, "n": 1.6, "k": 0.25}
    brdf = torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], **truth)
    return sza, vza, phi, brdf * (1 + 0.03 * rng.standard_normal(brdf.shape))


def test_three_blocks_are_flagged_many_samples_are_not():
    sza, vza, phi, brdf = _scene(1500)
    few = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf, clusters=np.arange(1500) % 3)
    assert few["n_clusters"] == 3
    assert few["errors_reliable"] is False
    assert "3 spatial blocks" in few["errors_reason"]
    assert np.all(few["error_dof"] <= 2.0 + 1e-9)  # at most G - 1
    many = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf)
    assert many["errors_reliable"] is True and many["errors_reason"] == ""
    assert np.all(many["error_dof"] >= MIN_ERROR_DOF)


def _two_bands(n):
    """RTLSR samples of two bands (the second twice the first) with 2 % independent noise."""
    rng = np.random.default_rng(0)
    sza, vza, phi = rng.uniform(30, 40, n), rng.uniform(0, 40, n), rng.choice([30.0, 150.0], n)
    brdf = get_model("ross_thick_li_sparse")(sza, vza, phi, f_iso=0.1, f_vol=0.05, f_geo=0.02)
    return sza, vza, phi, np.column_stack([brdf, 2 * brdf]) * (1 + 0.02 * rng.standard_normal((n, 2)))


def test_one_block_gives_no_errors_and_no_fit_block():
    # The residuals of one block sum to ~0 at the fit: its cluster-robust covariance was ~1e-10 (a
    # sigma 1e7 times too small, written to the table) where nothing can be estimated.
    sza, vza, phi, brdf = _two_bands(600)
    fit = fit_one_class(1, "field", "ross_thick_li_sparse", ClassSamples(sza, vza, phi, brdf, block=np.zeros(600)))
    assert fit.status == "fitted" and np.isfinite(fit.params["f_iso"]).all()  # the fit itself stands
    assert all(np.isnan(errors).all() for errors in fit.errors.values())
    assert fit.errors_reliable is False and fit.errors_reason.startswith("all samples in one spatial block")
    assert class_entry(fit, [560.0, 860.0], "test").fit is None  # no covariance: a NaN 1-sigma downstream
    # fit-classes' printed table shows the values of the shape without an error (it dropped them).
    from brdfcorr.cli.fitting import _class_row

    rpv = fit_one_class(1, "field", "rpv", ClassSamples(sza, vza, phi, brdf, block=np.zeros(600)))
    shape = _class_row(rpv)["shape"]
    assert all(f"{name}=" in shape for name in ("k", "theta", "rho_c")) and "±" not in shape


def test_a_shape_parameter_on_its_closed_bound_is_flagged():
    # RPV's rho_c ends on its physical bound 0 in about a fifth of noisy fits of a surface with
    # rho_c near 0: the estimate's distribution is cut off there, and the flag passed exactly those.
    rng = np.random.default_rng(0)
    sza, vza, phi = rng.uniform(25, 45, 600), rng.uniform(0, 45, 600), rng.uniform(0, 180, 600)
    brdf = get_model("rpv")(sza, vza, phi, rho0=0.1, k=0.75, theta=-0.1, rho_c=0.0)
    noisy = (brdf * (1 + 0.03 * np.random.default_rng(1).standard_normal(600)))[:, None]
    result = fit_class_samples("rpv", sza, vza, phi, noisy, clusters=np.arange(600) // 10)
    assert result["params"]["rho_c"][0] == 0.0  # this draw ends on the bound
    assert result["errors_reliable"] is False and "rho_c = 0 (at its bound)" in result["errors_reason"]


def test_samples_with_a_nan_are_left_out_with_a_note():
    # A NaN in one band of 10 samples gave that band f_iso = f_vol = f_geo = 0 ("fitted", no reason)
    # and dropped the class's covariance for every band.
    sza, vza, phi, brdf = _two_bands(2000)
    gappy = brdf.copy()
    gappy[:10, 1] = np.nan
    blocks = np.arange(2000) // 50
    fit = fit_one_class(1, "lawn", "ross_thick_li_sparse", ClassSamples(sza, vza, phi, gappy, block=blocks))
    assert "10 of 2000 samples left out: a non-finite angle or BRDF" in fit.notes and fit.n_samples == 1990
    kept = fit_one_class(1, "lawn", "ross_thick_li_sparse",
                         ClassSamples(sza[10:], vza[10:], phi[10:], brdf[10:], block=blocks[10:]))
    for name in ("f_iso", "f_vol", "f_geo"):  # the same fit as without those samples
        np.testing.assert_array_equal(fit.params[name], kept.params[name])
    assert class_entry(fit, [560.0, 860.0], "test").fit is not None


def test_material_class_sigma_is_the_hand_propagated_one():
    # One pixel of a roof_tile (library) class: sigma = R sqrt(sum_a (dF/dp_a sigma_a)^2) over the
    # published errors of t0, t1, w, n (k was held fixed by the authors), dF/dp by Richardson-
    # extrapolated central differences of the public model.
    material = load_material("roof_tile")
    geometry = {"sza": 40.0, "saa": 0.0, "vza": 20.0, "vaa": 150.0}
    layers = {name: xr.DataArray(np.array([[value]]), dims=("y", "x")) for name, value in geometry.items()}
    classes = xr.DataArray(np.array([[1]], np.uint8), dims=("y", "x"))
    reflectance = xr.DataArray(np.full((1, 1, 1), 0.3), dims=("band", "y", "x"), attrs={"units": "1"})
    table = ParameterTable(classes=[{"id": 1, "material": "roof_tile"}])
    with pytest.warns(BrdfcorrWarning, match="published 1-sigma errors of material roof_tile"):
        sigma = correction_uncertainty(reflectance, classes, layers, table, {"sza": 40.0, "vza": 0.0, "raa": 0.0})

    def factor(params):
        return (torrance_sparrow(40.0, 0.0, 0.0, **params) / torrance_sparrow(40.0, 20.0, 150.0, **params))

    def derivative(name):
        def central(h):
            return (factor({**material.params, name: material.params[name] + h})
                    - factor({**material.params, name: material.params[name] - h})) / (2 * h)
        h = 1e-3 * abs(material.params[name])
        return (4 * central(h / 2) - central(h)) / 3

    expected = 0.3 * np.sqrt(sum((derivative(name) * material.errors[name]) ** 2 for name in ("t0", "t1", "w", "n")))
    np.testing.assert_allclose(float(sigma.values[0, 0, 0]), expected, rtol=1e-6)


def test_a_fitted_class_gives_no_material_warning():
    table = ParameterTable(classes=[{"id": 1, "name": "x", "model": "lambertian", "params": {"t0": 0.1}}])
    layers = {name: xr.DataArray(np.array([[30.0]]), dims=("y", "x")) for name in ("sza", "saa", "vza", "vaa")}
    with warnings.catch_warnings():
        warnings.simplefilter("error", BrdfcorrWarning)
        sigma = correction_uncertainty(xr.DataArray(np.ones((1, 1, 1)), dims=("band", "y", "x")),
                                       xr.DataArray(np.array([[1]], np.uint8), dims=("y", "x")), layers, table)
    assert np.isnan(sigma.values).all()  # no fit, no material: nothing to propagate
