"""Tests of brdfcorr.correction.normalize: closed forms from rendered scenes, QA, nodata, laziness."""

from __future__ import annotations

import dask
import dask.array as da
import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

import brdfcorr
from brdfcorr.correction import QA, normalize, qa_counts
from brdfcorr.errors import GridMismatchError, InputError, ParameterError
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import REGISTRY, empirical, torrance_sparrow
from brdfcorr.params import ParameterTable
from brdfcorr.testing import example_table, render, synthetic_scene

ANGLES = ("sza", "saa", "vza", "vaa")


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=20, nx=28, dtype=np.float64)


def _run(scene, table=None, **options):
    table = example_table() if table is None else table
    return normalize(scene["reflectance"], scene["classes"], {a: scene[a] for a in ANGLES}, table, **options)


def _rendered_at(scene, table, sza, vza, raa):
    """The scene rendered at another geometry: saa = 0, vaa = raa gives relative azimuth raa."""
    shape = scene["classes"].shape
    return render(
        table, scene["classes"].values, np.broadcast_to(sza, shape), np.zeros(shape),
        np.full(shape, vza), np.full(shape, raa), wavelengths=scene["reflectance"]["wavelength"].values,
        brightness=scene["brightness"].values,
    )


@pytest.mark.parametrize("reference", [
    {"sza": 35.0, "vza": 0.0, "raa": 0.0},
    {"sza": 50.0, "vza": 20.0, "raa": 120.0},
    {"sza": 25.0, "vza": 30.0, "raa": 180.0},
])
def test_scene_at_a_normalized_to_b_equals_scene_rendered_at_b(scene, reference):
    # Closed form: reflectance = brightness * f(geometry), so normalizing to B gives brightness * f(B).
    table = example_table()
    corrected, qa = _run(scene, table, reference=reference, limits=None)
    expected = _rendered_at(scene, table, reference["sza"], reference["vza"], reference["raa"])
    np.testing.assert_allclose(corrected.values, expected, rtol=1e-12)
    assert not qa.values.any()


def test_observed_sun_zenith_keeps_each_pixels_sun(scene):
    table = example_table()
    corrected, _ = _run(scene, table, reference={"sza": "observed", "vza": 10.0, "raa": 60.0}, limits=None)
    expected = _rendered_at(scene, table, scene["sza"].values, 10.0, 60.0)
    np.testing.assert_allclose(corrected.values, expected, rtol=1e-12)


def test_mean_sun_zenith_is_the_scene_mean(scene):
    table = example_table()
    corrected, _ = _run(scene, table, reference={"sza": "mean"}, limits=None)
    mean = float(np.mean(scene["sza"].values.astype(np.float64)))
    np.testing.assert_allclose(corrected.values, _rendered_at(scene, table, mean, 0.0, 0.0), rtol=1e-12)
    assert corrected.attrs["brdf_reference"] == "sza=mean vza=0 raa=0"


def test_normalizing_twice_a_to_b_to_c_equals_rendered_at_c(scene):
    # B = (35, 0, 0) everywhere; its output, with B's angles as input, normalized to C = (35, 20, 90).
    table = example_table()
    at_b, _ = _run(scene, table, reference={"sza": 35.0}, limits=None)
    shape = scene["classes"].shape
    angles_b = {a: xr.DataArray(np.full(shape, v), dims=("y", "x")) for a, v in zip(ANGLES, (35.0, 0.0, 0.0, 0.0))}
    at_c, _ = normalize(at_b, scene["classes"], angles_b, table,
                        reference={"sza": "observed", "vza": 20.0, "raa": 90.0}, limits=None)
    np.testing.assert_allclose(at_c.values, _rendered_at(scene, table, 35.0, 20.0, 90.0), rtol=1e-12)


def test_float32_cube_stays_float32_and_close():
    scene32 = synthetic_scene(ny=12, nx=16, dtype=np.float32)
    table = example_table()
    corrected, _ = _run(scene32, table, reference={"sza": 35.0}, limits=None)
    assert corrected.dtype == np.float32
    expected = _rendered_at(scene32, table, 35.0, 0.0, 0.0)
    np.testing.assert_allclose(corrected.values, expected, rtol=2e-6)


def test_numpy_and_dask_give_identical_numbers(scene):
    reference = {"sza": 33.0, "vza": 5.0, "raa": 40.0}
    eager, eager_qa = _run(scene, reference=reference)
    chunked = {name: value.chunk({"y": 7, "x": 9}) for name, value in scene.items()}
    chunked["reflectance"] = scene["reflectance"].chunk({"band": 2, "y": 7, "x": 9})
    lazy, lazy_qa = _run(chunked, reference=reference)
    assert lazy.chunks == chunked["reflectance"].chunks  # chunks follow the input
    np.testing.assert_array_equal(lazy.values, eager.values)
    np.testing.assert_array_equal(lazy_qa.values, eager_qa.values)


def test_lazy_nothing_is_computed(scene):
    def forbidden(*args, **kwargs):
        raise AssertionError("normalize computed something")

    # Chunk the data only: coordinates (wavelength) stay numpy, as rioxarray opens them.
    chunked = {name: value.copy(data=da.from_array(value.values, chunks=10)) for name, value in scene.items()}
    with dask.config.set(scheduler=forbidden):
        corrected, qa = _run(chunked, reference={"sza": "mean"})
        counts = qa_counts(qa)
        assert isinstance(corrected.data, da.Array) and isinstance(qa.data, da.Array)
        assert all(isinstance(value, da.Array) for value in counts.values())
        with pytest.raises(AssertionError, match="computed"):
            corrected.values  # the guard works
    assert corrected.compute().shape == scene["reflectance"].shape


def test_result_keeps_dims_coords_attrs_and_georeference(scene):
    corrected, qa = _run(scene)
    reflectance = scene["reflectance"]
    assert corrected.dims == reflectance.dims
    for name in reflectance.coords:
        xr.testing.assert_identical(corrected[name], reflectance[name])
    assert corrected.rio.crs == reflectance.rio.crs
    assert corrected.rio.transform() == reflectance.rio.transform()
    assert corrected.attrs["long_name"] == reflectance.attrs["long_name"]  # band descriptions
    assert corrected.attrs["units"] == reflectance.attrs["units"]
    assert corrected.attrs["brdf_limits"] == "0.2,5"
    assert qa.dims == ("y", "x") and qa.dtype == np.uint8 and qa.rio.crs == reflectance.rio.crs
    assert qa.attrs["flag_meanings"].split() == [
        "nodata", "no_class", "unknown_class", "limited", "invalid_geometry", "facing_away",
        "topography_uncorrected", "band_uncorrected"]
    assert "wavelength" not in qa.coords and "band" not in qa.coords


def test_inputs_are_not_modified(scene):
    before = {name: value.copy(deep=True) for name, value in scene.items()}
    _run(scene, reference={"sza": 35.0})
    for name, value in scene.items():
        xr.testing.assert_identical(value, before[name])


def test_mixed_unknown_and_no_class(scene):
    classes = scene["classes"].copy()
    classes[0, :4] = 0  # no class
    classes[1, :4] = 9  # not in the table
    table = example_table()
    reference = {"sza": 35.0}
    corrected, qa = normalize(scene["reflectance"], classes, {a: scene[a] for a in ANGLES}, table,
                              reference=reference, limits=None)
    observed = scene["reflectance"].values
    np.testing.assert_array_equal(corrected.values[:, 0, :4], observed[:, 0, :4])  # factor 1
    np.testing.assert_array_equal(corrected.values[:, 1, :4], observed[:, 1, :4])
    assert (qa.values[0, :4] == QA.NO_CLASS).all() and (qa.values[1, :4] == QA.UNKNOWN_CLASS).all()
    expected = _rendered_at(scene, table, 35.0, 0.0, 0.0)
    np.testing.assert_allclose(corrected.values[:, 2:], expected[:, 2:], rtol=1e-12)
    counts = qa_counts(qa)
    assert (int(counts["no_class"]), int(counts["unknown_class"])) == (4, 4)
    assert int(counts["corrected"]) == classes.size - 8

    as_nan, _ = normalize(scene["reflectance"], classes, {a: scene[a] for a in ANGLES}, table,
                          reference=reference, unknown="nan")
    assert np.isnan(as_nan.values[:, :2, :4]).all()
    assert not np.isnan(as_nan.values[:, 2:]).any()


def test_per_wavelength_values_by_hand():
    # One grass pixel (empirical model) at 500 nm, between the table's 450 and 550 nm:
    # a = (0.01 + 0.02) / 2, t0 = (0.02 + 0.05) / 2 by linear interpolation.
    table = example_table()
    sza, vza, saa, vaa = 40.0, 30.0, 100.0, 280.0  # relative azimuth 180: forward
    reflectance = xr.DataArray(np.full((2, 1, 1), 0.2), dims=("band", "y", "x"),
                               coords={"wavelength": ("band", [500.0, 850.0])})
    one = lambda v: xr.DataArray(np.full((1, 1), v), dims=("y", "x"))  # noqa: E731
    corrected, _ = normalize(reflectance, one(2), {"sza": one(sza), "saa": one(saa), "vza": one(vza), "vaa": one(vaa)}, table,
                             reference={"sza": 30.0}, limits=None)
    f = lambda ti, tr, phi, a, t0: empirical(ti, tr, phi, a=a, b=1.0, c=0.02, t0=t0)  # noqa: E731
    expected_500 = 0.2 * f(30, 0, 0, 0.015, 0.035) / f(40, 30, 180, 0.015, 0.035)
    expected_850 = 0.2 * f(30, 0, 0, 0.05, 0.30) / f(40, 30, 180, 0.05, 0.30)
    np.testing.assert_allclose(corrected.values.ravel(), [expected_500, expected_850], rtol=1e-12)


def test_per_wavelength_out_of_range_and_extrapolation(scene):
    shifted = scene["reflectance"].assign_coords(wavelength=("band", [400.0, 560.0, 660.0, 830.0]))
    layers = [scene["classes"], {a: scene[a] for a in ANGLES}]
    with pytest.raises(ParameterError, match=r"class 2 \(grass\).*400 nm is outside"):
        normalize(shifted, *layers, example_table())
    corrected, _ = normalize(shifted, *layers, example_table(), extrapolate=True)
    assert np.isfinite(corrected.values).all()


def test_explicit_wavelengths_override_coordinate(scene):
    layers = [scene["classes"], {a: scene[a] for a in ANGLES}]
    bare = scene["reflectance"].drop_vars("wavelength")
    with pytest.raises(ParameterError, match="wavelengths are needed"):
        normalize(bare, *layers, example_table())
    a, _ = normalize(bare, *layers, example_table(), wavelengths=[480, 560, 660, 830])
    b, _ = normalize(scene["reflectance"], *layers, example_table())
    np.testing.assert_array_equal(a.values, b.values)


def test_limits_clip_and_flag():
    # A glossy roof tile seen near the forward specular direction (40, 40, 180) normalized to nadir:
    # the unlimited factor f(40, 0, 0) / f(40, 40, 180) from the model itself.
    table = ParameterTable(classes=[{"id": 1, "name": "tile", "model": "torrance_sparrow",
                                     "params": {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}}])
    params = table[1].params
    vza = np.array([[0.0, 10.0, 40.0]])
    factor = torrance_sparrow(40, 0, 0, **params) / torrance_sparrow(40, vza, 180.0, **params)
    assert factor[0, 2] < 0.8 < factor[0, 1]  # the specular pixel needs the strongest correction
    one = lambda v: xr.DataArray(np.broadcast_to(v, (1, 3)).astype(float), dims=("y", "x"))  # noqa: E731
    reflectance = xr.DataArray(np.ones((1, 1, 3)), dims=("band", "y", "x"))
    limits = (0.8, 1.25)
    corrected, qa = normalize(reflectance, one(1), {"sza": one(40.0), "saa": one(0.0), "vza": one(vza), "vaa": one(180.0)}, table,
                              reference={"sza": 40.0}, limits=limits, wavelengths=[550])
    np.testing.assert_allclose(corrected.values[0], np.clip(factor, *limits), rtol=1e-12)
    clipped = (factor < limits[0]) | (factor > limits[1])
    np.testing.assert_array_equal(qa.values & QA.LIMITED > 0, clipped)
    assert clipped.any()


def test_nodata_propagation(scene):
    reflectance = scene["reflectance"].copy()
    reflectance[1, 0, 0] = np.nan  # one band of one pixel
    sza = scene["sza"].copy()
    sza[0, 1] = np.nan  # an angle
    vza = scene["vza"].copy()
    vza[0, 2] = 95.0  # outside the model's domain
    classes = scene["classes"].copy()
    classes[0, 3] = 255  # the class map's nodata
    corrected, qa = normalize(reflectance, classes.rio.write_nodata(255),
                              {"sza": sza, "saa": scene["saa"], "vza": vza, "vaa": scene["vaa"]}, example_table(),
                              reference={"sza": 35.0})
    values = corrected.values
    assert np.isnan(values[1, 0, 0]) and np.isfinite(values[[0, 2, 3], 0, 0]).all()
    assert np.isnan(values[:, 0, 1:3]).all()
    # The class map's nodata means "no class" (DESIGN.md): unchanged and flagged.
    np.testing.assert_array_equal(values[:, 0, 3], reflectance.values[:, 0, 3])
    assert np.isfinite(values[:, 1:]).all() and np.isfinite(values[:, 0, 3:]).all()
    assert qa.values[0, 0] == QA.NODATA and qa.values[0, 1] == QA.NODATA and qa.values[0, 3] == QA.NO_CLASS
    assert qa.values[0, 2] == QA.INVALID_GEOMETRY
    assert int(qa_counts(qa)["nodata"]) == 3 and int(qa_counts(qa)["no_class"]) == 1


def test_class_nodata_from_rio(scene):
    classes = scene["classes"].copy()
    classes[2, 2] = 200
    classes = classes.rio.write_nodata(200)
    _, qa = normalize(scene["reflectance"], classes, {a: scene[a] for a in ANGLES}, example_table())
    assert qa.values[2, 2] == QA.NO_CLASS


def test_flip_view_azimuth(scene):
    flipped = (scene["vaa"] + 180.0) % 360.0
    a, _ = normalize(scene["reflectance"], scene["classes"],
                     {"sza": scene["sza"], "saa": scene["saa"], "vza": scene["vza"], "vaa": flipped},
                     example_table(), flip_view_azimuth=True)
    b, _ = _run(scene)
    np.testing.assert_allclose(a.values, b.values, rtol=1e-12)


def test_linear_split_matches_the_registry():
    # The optimization f = sum_j p_j B_j(shape) (Model.linear, Model.terms) must hold for every
    # registry kernel with linear parameters.
    rng = np.random.default_rng(3)
    geometry = ScatteringGeometry(rng.uniform(0, 80, 50), rng.uniform(0, 80, 50), rng.uniform(0, 180, 50))
    for model in REGISTRY.values():
        if not model.linear:
            continue
        params = {p.name: p.default * rng.uniform(0.5, 1.5) for p in model.parameters}
        terms = model.terms(geometry, params)
        assert len(terms) == len(model.linear)
        combined = sum(params[name] * term for name, term in zip(model.linear, terms))
        np.testing.assert_allclose(combined, model.kernel(geometry, **params), rtol=1e-12)


def test_band_independent_table_gives_the_same_factor_for_every_band(scene):
    table = ParameterTable(classes=[{"id": i, "name": f"c{i}", "model": "torrance_sparrow",
                                     "params": {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25}}
                                    for i in (1, 2, 3, 4)])
    corrected, _ = _run(scene, table, reference={"sza": 35.0})
    factor = corrected.values / scene["reflectance"].values
    np.testing.assert_allclose(factor, np.broadcast_to(factor[0], factor.shape), rtol=1e-12)


def test_accessor_delegates(scene):
    a, qa_a = scene["reflectance"].brdf.normalize(
        scene["classes"], {n: scene[n] for n in ANGLES}, example_table(), reference={"sza": 35.0})
    b, qa_b = brdfcorr.normalize(
        scene["reflectance"], scene["classes"], {n: scene[n] for n in ANGLES}, example_table(),
        reference={"sza": 35.0})
    xr.testing.assert_identical(a, b)
    xr.testing.assert_identical(qa_a, qa_b)


def test_reference_defaults_to_the_table_then_observed_nadir(scene):
    table = example_table(reference={"sza": 35.0, "vza": 0.0, "raa": 0.0})
    corrected, _ = _run(scene, table)
    assert corrected.attrs["brdf_reference"] == "sza=35 vza=0 raa=0"
    corrected, _ = _run(scene, example_table())
    assert corrected.attrs["brdf_reference"] == "sza=observed vza=0 raa=0"


def test_bad_inputs_have_clear_messages(scene):
    layers = [scene["classes"], {a: scene[a] for a in ANGLES}]
    with pytest.raises(GridMismatchError, match=r"vza is not on the grid of reflectance: shape \(rows, columns\) \(20, 27\) differs"):
        normalize(scene["reflectance"], scene["classes"],
                  {"sza": scene["sza"], "saa": scene["saa"], "vza": scene["vza"][:, :-1], "vaa": scene["vaa"]},
                  example_table())
    with pytest.raises(InputError, match="limits"):
        normalize(scene["reflectance"], *layers, example_table(), limits=(2.0, 5.0))
    with pytest.raises(InputError, match="unknown must be"):
        normalize(scene["reflectance"], *layers, example_table(), unknown="drop")
    with pytest.raises(ParameterError, match=r"reference geometry: reference\.vza"):
        normalize(scene["reflectance"], *layers, example_table(), reference={"vza": 90.0})
    with pytest.raises(InputError, match="3-D"):
        normalize(scene["reflectance"][0], *layers, example_table())
    other_crs = scene["classes"].rio.write_crs("EPSG:32633")
    with pytest.raises(GridMismatchError, match="classes is not on the grid of reflectance: CRS EPSG:32633 differs from EPSG:32632"):
        normalize(scene["reflectance"], other_crs, {a: scene[a] for a in ANGLES}, example_table())
    shifted = scene["sza"].assign_coords(x=scene["sza"]["x"] + 5.0)
    with pytest.raises(GridMismatchError, match=r"sza is not on the grid of reflectance: transform \(10\.0, 0\.0, 500005\.0"):
        normalize(scene["reflectance"], scene["classes"], {"sza": shifted, **{a: scene[a] for a in ANGLES[1:]}},
                  example_table())


@settings(max_examples=60, deadline=None)
@given(
    sza=st.floats(0, 85), vza=st.floats(0, 85), saa=st.floats(0, 360), vaa=st.floats(0, 360),
    class_id=st.sampled_from([1, 2, 3, 4]),
)
def test_reference_equal_to_the_observed_geometry_changes_nothing(sza, vza, saa, vaa, class_id):
    # Property: f(ref) / f(obs) = 1 when the reference is the observed geometry, for every model.
    one = lambda v: xr.DataArray(np.full((1, 1), v), dims=("y", "x"))  # noqa: E731
    phi = abs(saa - vaa) % 360.0
    phi = min(phi, 360.0 - phi)
    reflectance = xr.DataArray(np.full((2, 1, 1), 0.3), dims=("band", "y", "x"),
                               coords={"wavelength": ("band", [500.0, 800.0])})
    corrected, qa = normalize(reflectance, one(class_id), {"sza": one(sza), "saa": one(saa), "vza": one(vza), "vaa": one(vaa)},
                              example_table(), reference={"sza": "observed", "vza": vza, "raa": phi})
    np.testing.assert_allclose(corrected.values, 0.3, rtol=1e-9)
    assert qa.values[0, 0] == 0
