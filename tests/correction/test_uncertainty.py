"""Tests of brdfcorr.correction.uncertainty.correction_uncertainty: the 1-sigma of the corrected reflectance.

Sources of the expected values: a Monte-Carlo propagation through brdfcorr's own ``normalize``
(independent of the Jacobian), closed forms of the factor F = f(ref)/f(obs) for one parameter, and
properties that must hold (F = 1 for every parameter set at the reference geometry; nodata rules;
numpy = dask).
"""

from __future__ import annotations

import warnings

import dask
import dask.array as da
import numpy as np
import pytest
import xarray as xr

from brdfcorr.correction import normalize
from brdfcorr.correction.uncertainty import correction_uncertainty, difference_step, factor_jacobian
from brdfcorr.errors import BrdfcorrWarning, InputError, ParameterError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import REGISTRY, SURFACE_MODELS, kernel_driven, torrance_sparrow
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")
ROOF = {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}  # paper 003, Table 1 (roof tile)
LAWN = {"f_iso": 0.03, "f_vol": 0.02, "f_geo": 0.004}  # README's illustrative RTLSR weights [sr^-1]


def _fit(names, covariance) -> dict:
    """A ``fit:`` block with the given covariance: one matrix, or one per wavelength (3-D)."""
    covariance = np.asarray(covariance, dtype=float)
    errors = np.sqrt(np.diagonal(covariance, axis1=-2, axis2=-1))
    per_wavelength = covariance.ndim == 3
    count = covariance.shape[0] if per_wavelength else None
    return {
        "source": "test", "parameters": list(names), "covariance": covariance.tolist(),
        "n": [100] * count if per_wavelength else 100,
        "chi2_dof": [1.0] * count if per_wavelength else 1.0,
        "r2": [0.9] * count if per_wavelength else 0.9,
        "errors": {name: errors[..., i].tolist() for i, name in enumerate(names)},
    }


def _class(class_id, model, params, names=None, covariance=None):
    entry = {"id": class_id, "name": f"class{class_id}", "model": model, "params": params}
    if names is not None:
        entry["fit"] = _fit(names, covariance)
    return entry


def _table(*classes, reference=None) -> ParameterTable:
    return ParameterTable(reference=reference, classes=list(classes))


def _pixels(sza, saa, vza, vaa, classes=None, n_bands=1):
    """A one-row image of len(sza) pixels: reflectance 1 (so sigma = sigma_F), class 1 by default."""
    layers = {name: xr.DataArray(np.asarray(v, dtype=np.float64)[None, :], dims=("y", "x"))
              for name, v in zip(ANGLES, (sza, saa, vza, vaa))}
    n = layers["sza"].shape[1]
    layers["classes"] = xr.DataArray(np.ones((1, n), np.uint8) if classes is None else np.asarray(classes)[None, :],
                                     dims=("y", "x"))
    layers["reflectance"] = xr.DataArray(np.ones((n_bands, 1, n)), dims=("band", "y", "x"), attrs={"units": "1"})
    return layers


def _sigma(layers, table, slope=None, aspect=None, **options):
    angles = {a: layers[a] for a in ANGLES}
    angles.update({k: v for k, v in (("slope", slope), ("aspect", aspect)) if v is not None})
    return correction_uncertainty(layers["reflectance"], layers["classes"], angles, table, **options)


def _covariance(sd, correlation):
    sd = np.asarray(sd, dtype=float)
    return np.asarray(correlation, dtype=float) * np.outer(sd, sd)


# Geometries of the checks: near the forward specular peak, off it, backscatter (hotspot side),
# across the principal plane, and a grazing-ish view [deg].
SZA = [40.0, 40.0, 35.0, 50.0, 30.0]
SAA = [0.0, 0.0, 0.0, 0.0, 0.0]
VZA = [35.0, 20.0, 30.0, 45.0, 60.0]
VAA = [175.0, 150.0, 0.0, 90.0, 180.0]
REFERENCE = {"sza": 40.0, "vza": 0.0, "raa": 0.0}


# ------------------------------------------------------------------------------ Monte-Carlo check
MONTE_CARLO = {
    # Torrance-Sparrow, k fixed as in paper 003; t0/t1 anti-correlated as a fit of their sum makes them.
    "torrance_sparrow": (ROOF, ("t0", "t1", "w", "n"), [0.02 * ROOF["t0"], 0.02 * ROOF["t1"], 0.02 * ROOF["w"], 0.02],
                         [[1, -0.6, 0.2, 0], [-0.6, 1, -0.3, 0.4], [0.2, -0.3, 1, 0.1], [0, 0.4, 0.1, 1]]),
    "ross_thick_li_sparse": (LAWN, ("f_iso", "f_vol", "f_geo"), [0.0006, 0.0008, 0.0002],
                             [[1, -0.5, -0.4], [-0.5, 1, 0.3], [-0.4, 0.3, 1]]),
    "rpv": ({"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5}, ("rho0", "k", "theta", "rho_c"),
            [0.0006, 0.015, 0.01, 0.02], np.eye(4)),
}


@pytest.mark.parametrize("model", sorted(MONTE_CARLO))
def test_sigma_equals_the_spread_of_the_factor_over_parameter_draws(model):
    # Independent computation: 20 000 parameter sets drawn from the covariance (fixed seed), each
    # one band of a table, corrected by brdfcorr's own normalize at the same pixels; the sample SD
    # of its factor per pixel must equal the propagated sigma_F. Sampling error of an SD from
    # N = 20 000 draws: 1/sqrt(2N) = 0.5 %; with 2 % parameter SDs the first-order propagation is
    # exact to ~0.1 %; tolerance 2.5 % (5 sampling standard errors).
    params, names, sd, correlation = MONTE_CARLO[model]
    covariance = _covariance(sd, correlation)
    layers = _pixels(SZA, SAA, VZA, VAA)
    table = _table(_class(1, model, params, names, covariance))
    sigma = _sigma(layers, table, reference=REFERENCE, limits=None).values[0, 0]

    draws = np.random.default_rng(17).multivariate_normal([params[n] for n in names], covariance, size=20_000)
    drawn = {**params, **{name: draws[:, i].tolist() for i, name in enumerate(names)}}
    many = _pixels(SZA, SAA, VZA, VAA, n_bands=draws.shape[0])
    corrected = normalize(many["reflectance"], many["classes"], {a: many[a] for a in ANGLES},
                          _table(_class(1, model, drawn)), reference=REFERENCE, limits=None).reflectance
    spread = corrected.values[:, 0, :].std(axis=0, ddof=1)
    assert np.all(spread > 0)
    np.testing.assert_allclose(sigma, spread, rtol=0.025)


# --------------------------------------------------------------- every model, independent Jacobian
EVERY_MODEL = {
    "torrance_sparrow": ROOF,
    "torrance_sparrow_simplified": ROOF,
    "empirical": {"a": 0.02, "b": 1.5, "c": 0.03, "t0": 0.05},
    "lambertian": {"t0": 0.1},
    "ross_thick_li_sparse": LAWN,
    "ross_thin_li_sparse": LAWN,
    "ross_thick_li_dense": LAWN,
    "ross_thin_li_dense": LAWN,
    "rpv": {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5},
    "ross_li_ts": {**LAWN, "t1": 0.2, "w": 0.0362, "n": 1.77, "k": 0.25},
    "ross_li_peak": {**LAWN, "a": 0.02, "b": 1.5, "c": 0.03},
    "rpv_peak": {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5, "a": 0.02, "b": 1.5, "c": 0.03},
}


def test_every_surface_model_is_covered():
    assert set(EVERY_MODEL) == set(SURFACE_MODELS)


def _richardson(function, value, step):
    """Derivative by Richardson-extrapolated central differences (error O(step^4))."""
    d1 = (function(value + step) - function(value - step)) / (2 * step)
    d2 = (function(value + step / 2) - function(value - step / 2)) / step
    return (4 * d2 - d1) / 3


@pytest.mark.parametrize("model", sorted(EVERY_MODEL))
def test_sigma_equals_the_propagation_with_an_independent_jacobian(model):
    # Independent computation: dF/dp by Richardson differences of the public model call (the full
    # model function, not Model.terms; step 1e-3 of the value, error ~1e-12 relative), then
    # sqrt(J Sigma J^T) with a correlated covariance over every parameter, against the sigma of
    # correction_uncertainty at the same pixels.
    params = EVERY_MODEL[model]
    names = list(params)
    brdf = REGISTRY[model]
    phi = np.abs(np.subtract(SAA, VAA))
    phi = np.where(phi > 180, 360 - phi, phi)

    def factor(name, value):
        values = {**params, name: value}
        return brdf(REFERENCE["sza"], REFERENCE["vza"], REFERENCE["raa"], **values) / brdf(
            np.array(SZA), np.array(VZA), phi, **values)

    jacobian = np.column_stack([_richardson(lambda v: factor(name, v), params[name], 1e-3 * abs(params[name]))
                                for name in names])
    sd = [0.05 * abs(params[name]) for name in names]
    correlation = np.full((len(names), len(names)), 0.3) + 0.7 * np.eye(len(names))
    covariance = _covariance(sd, correlation)
    expected = np.sqrt(np.einsum("na,ab,nb->n", jacobian, covariance, jacobian))
    sigma = _sigma(_pixels(SZA, SAA, VZA, VAA), _table(_class(1, model, params, names, covariance)),
                   reference=REFERENCE, limits=None).values[0, 0]
    np.testing.assert_allclose(sigma, expected, rtol=1e-6, atol=1e-14)


# ---------------------------------------------------------------------------------- closed forms
def test_torrance_sparrow_t1_alone_closed_form():
    # f = t0 + t1 g (paper 003 eq. 1), F = (t0 + t1 g_ref) / (t0 + t1 g_obs); with only var(t1):
    # dF/dt1 = t0 (g_ref - g_obs) / f_obs^2, so sigma = observed * t0 |g_ref - g_obs| sd(t1) / f_obs^2,
    # g from the public torrance_sparrow with t0 = 0, t1 = 1. Observed reflectance 0.3 (sigma scales).
    sd = 0.01
    layers = _pixels(SZA, SAA, VZA, VAA)
    layers["reflectance"] = layers["reflectance"] * 0.3
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t1",), [[sd**2]]))
    sigma = _sigma(layers, table, reference=REFERENCE, limits=None).values[0, 0]

    shape = {name: ROOF[name] for name in ("w", "n", "k")}
    phi = np.abs(np.subtract(SAA, VAA)) % 360
    phi = np.where(phi > 180, 360 - phi, phi)
    g_obs = torrance_sparrow(np.array(SZA), np.array(VZA), phi, t0=0.0, t1=1.0, **shape)
    g_ref = torrance_sparrow(REFERENCE["sza"], REFERENCE["vza"], REFERENCE["raa"], t0=0.0, t1=1.0, **shape)
    f_obs = ROOF["t0"] + ROOF["t1"] * g_obs
    expected = 0.3 * ROOF["t0"] * np.abs(g_ref - g_obs) * sd / f_obs**2
    np.testing.assert_allclose(sigma, expected, rtol=1e-9)


def test_kernel_f_iso_alone_closed_form():
    # F = (f_iso + f_vol Kv_ref + f_geo Kg_ref) / f_obs, dF/df_iso = (f_obs - f_ref) / f_obs^2:
    # sigma = |f_obs - f_ref| sd(f_iso) / f_obs^2 with f from the public kernel_driven.
    sd = 0.002
    layers = _pixels(SZA, SAA, VZA, VAA)
    table = _table(_class(1, "ross_thick_li_sparse", LAWN, ("f_iso",), [[sd**2]]))
    sigma = _sigma(layers, table, reference=REFERENCE, limits=None).values[0, 0]
    phi = np.abs(np.subtract(SAA, VAA))
    f_obs = kernel_driven(np.array(SZA), np.array(VZA), np.where(phi > 180, 360 - phi, phi), **LAWN)
    f_ref = kernel_driven(REFERENCE["sza"], REFERENCE["vza"], REFERENCE["raa"], **LAWN)
    np.testing.assert_allclose(sigma, np.abs(f_obs - f_ref) * sd / f_obs**2, rtol=1e-9)


def _minnaert_product(geometry: ScatteringGeometry):
    return geometry.cos_i * geometry.cos_r * (geometry.cos_i + geometry.cos_r)


def test_rpv_shape_derivatives_closed_forms():
    # RPV f = rho0 P^(k-1) HG(theta) (1 + (1 - rho_c) / (1 + G)), P = cos ti cos tr (cos ti + cos tr):
    # dF/drho0 = 0 (rho0 cancels), dF/dk = F ln(P_ref / P_obs), and at rho_c = 1 (the upper bound,
    # where H = 1: a one-sided difference) dF/drho_c = F (1 / (1 + G_obs) - 1 / (1 + G_ref)).
    params = {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 1.0}
    phi = np.array([175.0, 150.0, 0.0, 90.0, 180.0])
    observed = ScatteringGeometry(np.array(SZA), np.array(VZA), phi)
    reference = ScatteringGeometry(np.float64(40.0), np.float64(0.0), np.float64(0.0))
    factor, jacobian = factor_jacobian(REGISTRY["rpv"], observed, reference, params, ("rho0", "k", "rho_c"))

    def distance(g):
        tan_i, tan_r = np.tan(np.radians(g.theta_i)), np.tan(np.radians(g.theta_r))
        return np.sqrt(tan_i**2 + tan_r**2 - 2 * tan_i * tan_r * np.cos(np.radians(g.phi)))

    # 0 up to the rounding of F, on the scale F / rho0 of a derivative by rho0:
    np.testing.assert_allclose(jacobian[:, 0], 0.0, atol=1e-12 * factor.max() / params["rho0"])
    log_ratio = np.log(_minnaert_product(reference) / _minnaert_product(observed))
    np.testing.assert_allclose(jacobian[:, 1], factor * log_ratio, rtol=1e-6)  # eq. 5: O(h^2) ~ 1e-10
    expected = factor * (1 / (1 + distance(observed)) - 1 / (1 + distance(reference)))
    np.testing.assert_allclose(jacobian[:, 2], expected, rtol=1e-6)
    assert all(offset <= 0 for offset, _ in difference_step(REGISTRY["rpv"], "rho_c", 1.0))


def test_difference_stencils_stay_in_the_parameter_range_and_differentiate_exactly_to_second_order():
    # k = 0 (Torrance-Sparrow's lower bound) and w just above its open bound: forward differences;
    # an interior value: central. Each stencil differentiates x^2 exactly (second order).
    model = REGISTRY["torrance_sparrow"]
    for name, value, kind in (("k", 0.0, "forward"), ("w", 1e-9, "forward"), ("n", 1.77, "central")):
        stencil = difference_step(model, name, value)
        offsets = [offset for offset, _ in stencil]
        assert (min(offsets) >= 0) == (kind == "forward"), (name, offsets)
        assert all(value + offset >= 0 for offset in offsets)
        if name == "w":
            assert all(value + offset > 0 for offset in offsets)
        derivative = sum(weight * (value + offset) ** 2 for offset, weight in stencil)
        np.testing.assert_allclose(derivative, 2 * value, atol=1e-6 * max(value, 1))


def test_observed_at_the_reference_geometry_has_zero_sigma():
    # Nadir view with the reference's sun (sza "observed", vza 0): F = 1 for every parameter set,
    # so J = 0 and sigma = 0, whatever the covariance, for every surface model: exactly for the
    # linear parameters (eq. 4), up to rounding for shape ones (eq. 5: F(s +- h) = 1 within a few
    # eps, divided by 2h = 2 eps^(1/3) |s|, times sd(s) = 0.1 |s|: ~1e-12).
    params = {"torrance_sparrow": ROOF, "ross_thick_li_dense": LAWN,
              "empirical": {"a": 0.02, "b": 1.0, "c": 0.02, "t0": 0.05},
              "rpv": {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5}}
    sza = np.array([10.0, 35.0, 60.0])
    layers = _pixels(sza, [0.0, 120.0, 300.0], [0.0, 0.0, 0.0], [0.0, 45.0, 200.0])
    for model, values in params.items():
        names = list(values)
        table = _table(_class(1, model, values, names, np.diag([(0.1 * max(abs(v), 0.01)) ** 2 for v in values.values()])))
        sigma = _sigma(layers, table, reference={"sza": "observed", "vza": 0.0, "raa": 0.0})
        np.testing.assert_allclose(sigma.values, 0.0, atol=1e-10, err_msg=model)


def test_a_time_cube_has_each_dates_sigma():
    import pandas as pd

    cov = np.diag([0.001**2, 0.01**2])
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1"), cov))
    dates = [_pixels([30.0 + 10 * d] * 4, [0.0] * 4, [10.0, 20.0, 30.0, 40.0], [170.0] * 4) for d in range(3)]
    time = pd.Index(pd.date_range("2024-06-01", periods=3), name="time")
    cube = xr.concat([layers["reflectance"] for layers in dates], dim=time)
    angles = {name: xr.concat([layers[name] for layers in dates], dim=time) for name in ANGLES}
    sigma = correction_uncertainty(cube, dates[0]["classes"], angles, table, reference=REFERENCE)
    assert sigma.dims == ("time", "band", "y", "x")
    for index, layers in enumerate(dates):
        np.testing.assert_array_equal(sigma.isel(time=index).values, _sigma(layers, table, reference=REFERENCE).values)


# ------------------------------------------------------------------------------------- nodata
def test_nodata_where_there_is_nothing_to_propagate():
    # Pixels: 0 class 1 with covariance, 1 class 2 without, 2 class 9 unknown, 3 class 0, 4 a zenith
    # of 95 deg, 5 a NaN reflectance, 6 a factor clipped by the limits (the specular direction), 7 class 1.
    cov = np.diag([0.001**2, 0.01**2])
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1"), cov), _class(2, "torrance_sparrow", ROOF))
    sza = [40, 40, 40, 40, 95, 40, 40, 40]
    vza = [20, 20, 20, 20, 20, 20, 40, 10]
    vaa = [170, 170, 170, 170, 170, 170, 180, 90]
    layers = _pixels(sza, [0] * 8, vza, vaa, classes=[1, 2, 9, 0, 1, 1, 1, 1])
    layers["reflectance"][0, 0, 5] = np.nan
    limits = (0.75, 1.5)  # F: 0.83 at pixel 0, 0.67 at the specular pixel 6, 1.01 at pixel 7
    corrected = normalize(layers["reflectance"], layers["classes"], {a: layers[a] for a in ANGLES}, table,
                          reference=REFERENCE, limits=limits)
    assert corrected.qa.values[0, 6] & 8  # the test's premise: pixel 6 is limited
    sigma = _sigma(layers, table, reference=REFERENCE, limits=limits).values[0, 0]
    assert np.isfinite(sigma[[0, 7]]).all() and (sigma[[0, 7]] > 0).all()
    assert np.isnan(sigma[1:7]).all()
    # Without limits the clipped pixel has a sigma.
    assert np.isfinite(_sigma(layers, table, reference=REFERENCE, limits=None).values[0, 0, 6])


def test_a_negative_reflectance_has_the_sigma_of_its_magnitude():
    # Eq. 3: sigma = |observed| sigma_F. Dark water after Sentinel-2's -0.1 offset reads below 0; the
    # 1-sigma of -0.01 is that of +0.01 (a standard deviation is never negative).
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1"), np.diag([0.001**2, 0.01**2])))
    layers = _pixels([40, 40], [0, 0], [20, 20], [170, 170])
    layers["reflectance"].values[0, 0] = [-0.01, 0.01]
    sigma = _sigma(layers, table, reference=REFERENCE).values[0, 0]
    assert sigma[1] > 0
    np.testing.assert_allclose(sigma[0], sigma[1], rtol=1e-12)


def test_the_table_can_be_a_file_as_for_normalize(tmp_path):
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1"), np.diag([0.001**2, 0.01**2])))
    path = tmp_path / "table.yaml"
    table.save(path)
    layers = _pixels(SZA, SAA, VZA, VAA)
    expected = _sigma(layers, table, reference=REFERENCE).values
    for given in (path, str(path)):
        np.testing.assert_array_equal(_sigma(layers, given, reference=REFERENCE).values, expected)


def test_a_table_without_covariance_gives_all_nodata_and_the_attrs():
    scene = synthetic_scene(ny=8, nx=8, dtype=np.float32)
    sigma = correction_uncertainty(scene["reflectance"], scene["classes"], {a: scene[a] for a in ANGLES},
                                   example_table())
    assert sigma.dims == ("band", "y", "x") and sigma.dtype == np.float32
    assert np.isnan(sigma.values).all()
    assert sigma.attrs["units"] == "1" and "1-sigma" in sigma.attrs["long_name"]
    assert "covariance" in sigma.attrs["description"]
    assert sigma.rio.crs == scene["reflectance"].rio.crs
    np.testing.assert_array_equal(sigma["wavelength"], scene["reflectance"]["wavelength"])


def test_bad_input_is_one_clear_error():
    layers = _pixels(SZA, SAA, VZA, VAA)
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t1",), [[1e-4]]))
    with pytest.raises(InputError, match="limits"):
        _sigma(layers, table, limits=(2.0, 5.0))
    with pytest.raises(InputError, match="ParameterTable"):
        correction_uncertainty(layers["reflectance"], layers["classes"], {a: layers[a] for a in ANGLES}, {})
    with pytest.raises(ParameterError, match="w"):
        factor_jacobian(REGISTRY["torrance_sparrow"], ScatteringGeometry(30.0, 10.0, 0.0),
                        ScatteringGeometry(30.0, 0.0, 0.0), {**ROOF, "w": -1.0}, ("t0",))


# ---------------------------------------------------------------------------------- laziness
def _scene_with_covariance():
    scene = synthetic_scene(ny=20, nx=28, dtype=np.float32)
    base = example_table()
    ts_cov = _covariance([0.001, 0.01, 0.002, 0.03], [[1, -0.5, 0, 0], [-0.5, 1, 0.2, 0], [0, 0.2, 1, 0], [0, 0, 0, 1]])
    grass = base[2]
    classes = [
        _class(1, "torrance_sparrow", ROOF, ("t0", "t1", "w", "n"), ts_cov),
        {**grass.model_dump(exclude_none=True, exclude={"material"}),  # per wavelength: one matrix each
         "fit": _fit(["a", "t0", "b"], [np.diag([1e-6, 4e-6, v]) for v in (1e-4, 2e-4, 1e-4, 3e-4)])},
        base[3].model_dump(exclude_none=True, exclude={"material"}),  # no covariance: nodata
        _class(4, "lambertian", {"t0": 0.1}, ("t0",), [[1e-4]]),
    ]
    return scene, _table(*classes)


def test_dask_equals_numpy_keeps_the_chunks_and_stays_lazy(no_compute):
    scene, table = _scene_with_covariance()
    # dask data, numpy coords (DataArray.chunk would chunk the wavelength coordinate too).
    chunks = {"band": 2, "y": 8, "x": 16}
    chunked = {name: layer.copy(data=da.from_array(layer.values, chunks=tuple(chunks[d] for d in layer.dims)))
               for name, layer in scene.items()}
    for reference in ({"sza": "mean", "vza": 0.0, "raa": 0.0}, {"sza": 30.0, "vza": 10.0, "raa": 90.0}):
        lazy = correction_uncertainty(chunked["reflectance"], chunked["classes"], {a: chunked[a] for a in ANGLES},
                                      table, reference=reference)
        assert isinstance(lazy.data, da.Array)
        assert lazy.chunks == chunked["reflectance"].chunks
        computed = lazy.data.compute(scheduler="sync")
        eager = correction_uncertainty(scene["reflectance"], scene["classes"], {a: scene[a] for a in ANGLES},
                                       table, reference=reference)
        np.testing.assert_array_equal(computed, eager.values)
        classes = scene["classes"].values
        assert np.isfinite(eager.values[:, classes != 3]).all()  # premise: every other class has a sigma
        assert np.isnan(eager.values[:, classes == 3]).all()
        # Lambertian: F = 1 for any t0, so sigma = 0.
        assert (eager.values[:, classes == 4] == 0).all()


def test_computed_with_the_correction_each_input_chunk_is_read_once():
    scene, table = _scene_with_covariance()
    reads: list[tuple] = []

    def counted(block, block_info=None):
        reads.append(tuple(block_info[0]["chunk-location"]))
        return block

    reflectance = scene["reflectance"].copy(data=da.from_array(scene["reflectance"].values, chunks=(4, 10, 14))
                                            .map_blocks(counted, dtype=np.float32))
    arguments = (reflectance, scene["classes"], {a: scene[a] for a in ANGLES}, table)
    corrected = normalize(*arguments, reference={"sza": "mean"}).reflectance
    sigma = correction_uncertainty(*arguments, reference={"sza": "mean"})
    with dask.config.set(scheduler="sync"):
        dask.compute(corrected.data, sigma.data)
    assert sorted(reads) == sorted(set(reads)) and len(reads) == 4  # 1 x 2 x 2 chunks, each read once


# ---------------------------------------------------------------------------------- terrain
def test_tilted_surfaces_take_the_geometry_in_their_own_frame():
    # Property (the rule of normalize): with slope/aspect and a fixed reference, sigma equals that of
    # a flat pixel observed at the local angles (brdfcorr.correction.terrain.local_angles); slope 0 gives the
    # flat result bit for bit; a sun behind the surface (pixel 2: a 60 deg slope facing away from a
    # sun at 40 deg) is nodata. Dask gives the numpy result.
    from brdfcorr.correction.terrain import local_angles

    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1", "w"), np.diag([1e-6, 1e-4, 4e-6])),
                   _class(2, "rpv", {"rho0": 0.03, "k": 0.75, "theta": -0.1, "rho_c": 0.5}, ("k", "theta"),
                          np.diag([1e-4, 1e-4])))
    sza, saa, vza, vaa = [40.0, 35.0, 40.0, 30.0], [0.0, 90.0, 0.0, 200.0], [20.0, 10.0, 5.0, 30.0], [170.0, 0, 0, 20]
    slope, aspect = np.array([[20.0, 10.0, 60.0, 15.0]]), np.array([[0.0, 45.0, 180.0, 300.0]])
    layers = _pixels(sza, saa, vza, vaa, classes=[1, 2, 1, 2])
    terrain = {"slope": xr.DataArray(slope, dims=("y", "x")), "aspect": xr.DataArray(aspect, dims=("y", "x"))}
    tilted = _sigma(layers, table, reference=REFERENCE, **terrain).values

    local = local_angles(*(np.array(v) for v in (sza, saa, vza, vaa)), slope[0], aspect[0])
    assert local.sza[2] >= 90  # the premise: pixel 2 faces away from the sun
    flat = _sigma(_pixels(local.sza, local.saa, local.vza, local.vaa, classes=[1, 2, 1, 2]), table,
                  reference=REFERENCE).values
    keep = [0, 1, 3]
    np.testing.assert_allclose(tilted[..., keep], flat[..., keep], rtol=1e-12)
    assert np.isfinite(tilted[..., keep]).all() and np.isnan(tilted[..., 2]).all()

    level = {name: layer * 0 for name, layer in terrain.items()}
    np.testing.assert_array_equal(_sigma(layers, table, reference=REFERENCE, **level).values,
                                  _sigma(layers, table, reference=REFERENCE).values)
    lazy = {name: layer.chunk({"x": 2}) for name, layer in terrain.items()}
    np.testing.assert_array_equal(_sigma(layers, table, reference=REFERENCE, **lazy).values, tilted)
    with pytest.raises(InputError, match="slope and aspect"):
        _sigma(layers, table, slope=terrain["slope"])


def test_a_covariance_that_is_not_positive_semi_definite_is_refused():
    # [[1, 2], [2, 1]] * 1e-4 is symmetric with a non-negative diagonal (the table accepts it) but
    # has the eigenvalue -1e-4: no covariance matrix.
    layers = _pixels(SZA, SAA, VZA, VAA)
    table = _table(_class(1, "torrance_sparrow", ROOF, ("t0", "t1"), [[1e-4, 2e-4], [2e-4, 1e-4]]))
    with pytest.raises(ParameterError, match="not positive semi-definite"):
        _sigma(layers, table)


def test_errors_the_fit_flagged_unreliable_are_propagated_with_a_warning():
    # The same sigma either way (the covariance is what it is); the flag is said once, per class.
    sd, layers = 0.002, _pixels(SZA, SAA, VZA, VAA)
    trusted = _class(1, "ross_thick_li_sparse", LAWN, ("f_iso",), [[sd**2]])
    flagged = {**trusted, "fit": {**trusted["fit"], "errors_reliable": False, "errors_reason": "errors from 3 blocks"}}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        reference = _sigma(layers, _table(trusted), reference=REFERENCE, limits=None).values
    assert not [w for w in caught if "unreliable" in str(w.message)]
    with pytest.warns(BrdfcorrWarning, match=r"errors of class 1 \(class1\) unreliable"):
        rough = _sigma(layers, _table(flagged), reference=REFERENCE, limits=None).values
    np.testing.assert_array_equal(rough, reference)
