"""Calibration of the imagery fit's errors (issue 17): the joint sandwich covariance of
:func:`brdfcorr.fit.solver.fit_class_samples`.

Two checks. (1) The plain (CR0) covariance equals the sandwich ``H^-1 M H^-1`` computed
independently, by brute force: the full Jacobian over every free parameter by finite differences
of the model function, H = J^T W J, the meat from per-cluster score sums (the small-sample
corrections of issue 27, CR2 and the t-variance factor, are checked in
``tests/fit/test_small_sample_errors.py``). (2) Over seeds, the pulls ``(fit - truth) /
error`` have a standard deviation near 1 for additive, multiplicative and block-correlated noise.
The full 400-seed sweep, with the 0.9-1.1 band of issue 17, is ``benchmarks/bench_fit_calibration.py``
(about a minute per noise kind); here 100 seeds of a smaller class keep the test fast, with the band
widened to 0.8-1.2 for their larger sampling error (1 / sqrt(2 * 100) = 0.07 per SD, so the band
is +-2.8 sampling errors; the errors of brdfcorr 0.2, 0.77 for t0 under multiplicative noise,
fall outside it).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from brdfcorr.fit.profile import _profile
from brdfcorr.fit.sandwich import _joint_covariance
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import get_model, torrance_sparrow

_BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_fit_calibration.py"
_spec = importlib.util.spec_from_file_location("bench_fit_calibration", _BENCH)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)  # type: ignore[union-attr]


def _model(phi_vector, geometry):
    """BRDF (N, 2) at phi = (w, n, t0_1, t1_1, t0_2, t1_2), k fixed at 0.25."""
    w, n, t0a, t1a, t0b, t1b = phi_vector
    sza, vza, phi = geometry
    return torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], t0=np.array([t0a, t0b]),
                            t1=np.array([t1a, t1b]), w=w, n=n, k=0.25)


def _brute_force_sandwich(result, geometry, brdf, clusters):
    """H^-1 M H^-1 over all six free parameters, with everything formed explicitly."""
    p = result["params"]
    estimate = np.array([p["w"][0], p["n"][0], p["t0"][0], p["t1"][0], p["t0"][1], p["t1"][1]])
    jacobian = np.empty(brdf.shape + (6,))  # (N, B, P)
    for i in range(6):
        step = 1e-6 * max(abs(estimate[i]), 1e-2)
        up, down = estimate.copy(), estimate.copy()
        up[i] += step
        down[i] -= step
        jacobian[..., i] = (_model(up, geometry) - _model(down, geometry)) / (2 * step)
    weights = 1.0 / brdf.var(axis=0)  # the solver's band weights: inverse data variance
    residuals = brdf - _model(estimate, geometry)
    hessian = np.einsum("nbi,b,nbj->ij", jacobian, weights, jacobian)
    scores = np.einsum("nbi,b,nb->ni", jacobian, weights, residuals)
    _, index = np.unique(clusters, return_inverse=True)
    summed = np.zeros((index.max() + 1, 6))
    np.add.at(summed, index, scores)
    inverse = np.linalg.inv(hessian)
    return inverse @ (summed.T @ summed) @ inverse  # CR0: no small-sample correction


@pytest.mark.parametrize("kind", ["multiplicative", "block"])
def test_covariance_is_the_joint_sandwich(kind):
    sza, vza, phi, brdf, blocks = bench.synthetic_class(7, kind, n=600, block=10)
    result = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf, clusters=blocks)
    expected = _brute_force_sandwich(result, (sza, vza, phi), brdf, blocks)
    assert result["free"] == ("t0", "t1", "w", "n")
    profile = _profile(get_model("torrance_sparrow"), sza, vza, phi, brdf, {"k": 0.25})
    shape = {name: result["params"][name][0] for name in ("w", "n")}
    intensities = np.stack([result["params"]["t0"], result["params"]["t1"]])
    plain = _joint_covariance(profile, shape, profile.design(shape), intensities, blocks, small_sample=False)
    for band in (0, 1):
        rows = [0, 1, 2 + 2 * band, 3 + 2 * band]  # w, n, t0_b, t1_b in the brute-force order
        # Finite differences of the design in the solver (steps 1e-3) vs of the model here (1e-6),
        # and the solver's Schur-complement algebra: measured agreement 3e-6, allowed 1e-4.
        block = expected[np.ix_(rows, rows)]
        scale = np.sqrt(np.outer(np.diag(block), np.diag(block)))  # in units of sigma_i sigma_j
        np.testing.assert_allclose(plain.covariance[band] / scale, block / scale, rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(result["errors"]["t1"], np.sqrt(result["covariance"][:, 1, 1]))
    np.testing.assert_array_equal(result["errors"]["k"], [0.0, 0.0])  # fixed


def test_without_clusters_every_sample_is_its_own():
    sza, vza, phi, brdf, _ = bench.synthetic_class(3, "multiplicative", n=600)
    alone = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf)
    own = fit_class_samples("torrance_sparrow", sza, vza, phi, brdf, clusters=np.arange(600))
    # HC2 (per-sample leverage) is CR2 with singleton clusters: equal, and so are the dof.
    np.testing.assert_allclose(alone["covariance"], own["covariance"], rtol=1e-9)
    np.testing.assert_allclose(alone["error_dof"], own["error_dof"], rtol=1e-9)


def test_kernel_model_covariance_is_the_linear_sandwich():
    # No shape parameter: the intensities' HC2 sandwich (A^T A)^-1 A^T diag(r^2 / (1 - h)) A (A^T A)^-1
    # (MacKinnon and White 1985), h the diagonal of the hat matrix, times the t-variance factor of
    # its degrees of freedom (checked on their own in tests/fit/test_small_sample_errors.py).
    rng = np.random.default_rng(1)
    n = 400
    sza, vza, phi = rng.uniform(20, 50, n), rng.uniform(0, 40, n), rng.uniform(0, 180, n)
    model = get_model("ross_thick_li_sparse")
    design = np.column_stack([np.broadcast_to(np.asarray(t, float), (n,)) for t in
                              model.terms(ScatteringGeometry(sza, vza, phi), {})])
    truth = np.array([0.05, 0.02, 0.01])
    brdf = (design @ truth) * (1 + 0.05 * rng.standard_normal(n))
    result = fit_class_samples(model, sza, vza, phi, brdf[:, None])
    bread = np.linalg.inv(design.T @ design)
    hat = design @ bread @ design.T
    residuals = brdf - hat @ brdf
    expected = bread @ (design.T * residuals**2 / (1 - np.diag(hat))) @ design @ bread
    factor = np.sqrt(result["error_dof"][0] / (result["error_dof"][0] - 2))
    np.testing.assert_allclose(result["covariance"][0], expected * np.outer(factor, factor), rtol=1e-8)


@pytest.mark.parametrize("kind", bench.NOISE_KINDS)
def test_pull_standard_deviations_near_one(kind):
    found = bench.pulls(kind, seeds=100, n=1000, block=10)
    for name, values in found.items():
        sd = values.std(axis=0, ddof=1)
        assert np.all((sd > 0.8) & (sd < 1.2)), f"{kind}: pull SD of {name} = {sd}"
