"""Coefficients continuous in NDVI (issue 24, FlexBRDF parity): ``ndvi_interpolation`` in a
parameter table, :mod:`brdfcorr.correction.continuous`.

Sources: the interpolation rule is linear between the classes' NDVI centres and clamped outside
(docstring of :mod:`brdfcorr.correction.continuous`; FlexBRDF, Queally et al. 2022, sect. 2.3,
interpolates kernel weights between NDVI bin centres); expected factors are computed independently
with the registered model function, f(ref; p) / f(obs; p).
"""

from __future__ import annotations

import json

import dask
import dask.array
import numpy as np
import pytest
import rasterio
import xarray as xr
from click.testing import CliRunner

from brdfcorr import normalize
from brdfcorr.cli import main
from brdfcorr.correction.continuous import interpolated_coefficients, interpolation_weights
from brdfcorr.errors import ParameterError
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import get_model
from brdfcorr.params import ParameterTable
from brdfcorr.testing import georeference, write_scene

RTLSR = get_model("ross_thick_li_sparse")
WAVELENGTHS = [550.0, 660.0, 860.0]  # green (BRDF varies with NDVI), red, NIR (the NDVI bands)
CENTRES = [0.2, 0.4, 0.6]


# ------------------------------------------------------------------------- closed forms
def test_weights_at_centres_midway_and_outside():
    lower, t = interpolation_weights(np.array([0.2, 0.4, 0.6, 0.3, 0.5, -0.5, 0.9]), CENTRES)
    assert lower.tolist() == [0, 1, 1, 0, 1, 0, 1]
    assert t.tolist() == [0.0, 0.0, 1.0, pytest.approx(0.5), pytest.approx(0.5), 0.0, 1.0]


def test_coefficients_at_a_centre_exactly_midway_the_mean_clamped_outside():
    rows = np.array([[0.1, 0.03, 0.011], [0.2, 0.07, 0.013], [0.35, 0.2, 0.017]])
    at = interpolated_coefficients(rows, np.array([0.2, 0.4, 0.6]), CENTRES)
    assert np.array_equal(at, rows)  # a pixel at a bin centre gets that bin's weights exactly
    midway = interpolated_coefficients(rows, np.array([0.3, 0.5]), CENTRES)
    np.testing.assert_allclose(midway, [(rows[0] + rows[1]) / 2, (rows[1] + rows[2]) / 2], rtol=1e-15)
    outside = interpolated_coefficients(rows, np.array([-1.0, 0.1, 0.7, 2.0]), CENTRES)
    assert np.array_equal(outside, rows[[0, 0, 2, 2]])  # clamped, not extrapolated


# ------------------------------------------------------------------------- a synthetic scene
def truth_coefficients(x):
    """Green-band RTLSR weights [sr^-1] varying linearly with NDVI ``x``; red and NIR are
    Lambertian with f_iso = (1 - x) / 10 and (1 + x) / 10, so the observed NDVI is ``x`` exactly
    at every geometry."""
    x = np.asarray(x, dtype=float)
    green = {"f_iso": 0.03 + 0.05 * x, "f_vol": 0.002 + 0.06 * x, "f_geo": 0.012 - 0.01 * x}
    return {name: np.stack([green[name], *(((1 - x) / 10, (1 + x) / 10) if name == "f_iso"
                                            else (0.0 * x, 0.0 * x))]) for name in green}


def scene(rows=40, columns=60, seed=3):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.1, 0.7, (rows, columns))
    vza = np.broadcast_to(np.abs(np.linspace(-30, 30, columns)), (rows, columns))
    angles = {"sza": np.full((rows, columns), 40.0), "saa": np.full((rows, columns), 120.0), "vza": vza,
              "vaa": np.broadcast_to(np.where(np.linspace(-1, 1, columns) > 0, 270.0, 90.0), (rows, columns))}
    phi = relative_azimuth(angles["saa"], angles["vaa"])
    weights = truth_coefficients(x)
    observed = np.pi * RTLSR(angles["sza"], angles["vza"], phi, **weights)
    truth = np.pi * RTLSR(40.0, 0.0, 0.0, **weights)
    image = xr.DataArray(observed, dims=("band", "y", "x"), coords={"wavelength": ("band", WAVELENGTHS)})
    layers = xr.Dataset({k: (("y", "x"), np.asarray(v)) for k, v in angles.items()})
    strata = np.digitize(x, [0.3, 0.5]).astype(np.uint8) + 1
    return image, layers, strata, x, truth


def stratum_table(strata, x, interpolate: bool, centres: bool = False) -> ParameterTable:
    """Each stratum's coefficients are the truth at its mean NDVI (what a fit of a linear truth gives)."""
    means = [float(x[strata == k].mean()) for k in (1, 2, 3)]
    classes = []
    for k, mean in zip((1, 2, 3), means):
        params = {name: values.tolist() for name, values in truth_coefficients(mean).items()}
        classes.append({"id": k, "name": f"s{k}", "model": "ross_thick_li_sparse", "params": params})
    document = {"classes": classes}
    if interpolate:
        document["ndvi_interpolation"] = {"classes": [1, 2, 3], **({"centres": means} if centres else {})}
    return ParameterTable.from_dict(document)


def reference():
    return {"sza": 40.0, "vza": 0.0, "raa": 0.0}


@pytest.mark.parametrize("chunked", [False, True])
def test_continuous_correction_leaves_less_residual_than_binned(chunked):
    image, angles, strata, x, truth = scene()
    if chunked:
        image, angles = image.chunk({"band": 1, "y": 16, "x": 32}), angles.chunk({"y": 16, "x": 32})
    classes = xr.DataArray(strata, dims=("y", "x"))
    binned = normalize(image, classes, angles, stratum_table(strata, x, False), reference()).reflectance
    continuous = normalize(image, classes, angles, stratum_table(strata, x, True), reference()).reflectance
    error_binned = np.abs(np.asarray(binned[0]) / truth[0] - 1)
    error_continuous = np.abs(np.asarray(continuous[0]) / truth[0] - 1)
    means = [x[strata == k].mean() for k in (1, 2, 3)]
    inside = (x >= means[0]) & (x <= means[-1])
    # The truth is linear in NDVI: between the first and last centre the interpolation is exact.
    assert error_continuous[inside].max() < 1e-12
    assert np.median(error_continuous) < 0.1 * np.median(error_binned)
    assert error_binned[inside].max() > 1e-3  # the binned correction has a residual to remove
    # Red and NIR are Lambertian in every class: factor 1 either way.
    np.testing.assert_allclose(np.asarray(continuous[1:]), np.asarray(image[1:]), rtol=1e-12)


def test_lazy_with_given_centres_one_computation_with_measured_ones():
    """Given centres: nothing is computed until asked (as without interpolation). Measured centres:
    one computation, of the class means, before the correction is asked for."""
    image, angles, strata, x, _ = scene()
    # Chunk the data only: coordinates (wavelength) stay numpy, as rioxarray opens them.
    image = image.copy(data=dask.array.from_array(image.values, chunks=(1, 16, 32)))
    angles = angles.chunk({"y": 16, "x": 32})
    classes = xr.DataArray(strata, dims=("y", "x")).chunk({"y": 16, "x": 32})
    computations = []

    def counting(graph, keys, **kwargs):
        computations.append(keys)
        return dask.get(graph, keys, **kwargs)

    with dask.config.set(scheduler=counting):
        corrected = normalize(image, classes, angles, stratum_table(strata, x, True, centres=True),
                              reference()).reflectance
        assert computations == [] and isinstance(corrected.data, dask.array.Array)
        normalize(image, classes, angles, stratum_table(strata, x, True), reference())
        assert len(computations) == 1


def test_given_centres_match_measured_ones():
    image, angles, strata, x, _ = scene()
    classes = xr.DataArray(strata, dims=("y", "x"))
    measured = normalize(image, classes, angles, stratum_table(strata, x, True), reference()).reflectance
    given = normalize(image, classes, angles, stratum_table(strata, x, True, centres=True), reference()).reflectance
    np.testing.assert_allclose(np.asarray(given), np.asarray(measured), rtol=1e-12)


def test_a_pixel_gets_the_factor_of_its_interpolated_coefficients():
    """Independent computation: the factor f(ref; p(x)) / f(obs; p(x)) with the registered model,
    p(x) interpolated by hand, for a pixel midway between two centres in the map's class 1."""
    image, angles, strata, x, _ = scene(rows=2, columns=3)
    x = np.full((2, 3), 0.3)  # midway between the first two centres
    weights = truth_coefficients(x)
    phi = relative_azimuth(angles["saa"].values, angles["vaa"].values)
    observed = np.pi * RTLSR(angles["sza"].values, angles["vza"].values, phi, **weights)
    image = image.copy(data=observed)
    table = ParameterTable.from_dict({
        "classes": [{"id": k, "name": f"s{k}", "model": "ross_thick_li_sparse",
                     "params": {n: v.tolist() for n, v in truth_coefficients(c).items()}}
                    for k, c in zip((1, 2, 3), CENTRES)],
        "ndvi_interpolation": {"classes": [1, 2, 3], "centres": CENTRES}})
    corrected = normalize(image, xr.DataArray(np.ones((2, 3), np.uint8), dims=("y", "x")), angles, table,
                          reference()).reflectance
    p = {n: (truth_coefficients(0.2)[n][0] + truth_coefficients(0.4)[n][0]) / 2 for n in ("f_iso", "f_vol", "f_geo")}
    factor = RTLSR(40.0, 0.0, 0.0, **p) / RTLSR(angles["sza"].values, angles["vza"].values, phi, **p)
    np.testing.assert_allclose(np.asarray(corrected[0]), observed[0] * factor, rtol=1e-12)


def test_undefined_ndvi_keeps_the_own_class_and_one_class_present_is_binned():
    image, angles, strata, x, _ = scene()
    classes = xr.DataArray(strata, dims=("y", "x"))
    data = image.values.copy()
    data[1:, 0, :4] = 0.0  # red + NIR = 0: NDVI undefined in four pixels
    image = image.copy(data=data)
    binned = normalize(image, classes, angles, stratum_table(strata, x, False), reference()).reflectance
    continuous = normalize(image, classes, angles, stratum_table(strata, x, True, centres=True),
                           reference()).reflectance
    np.testing.assert_array_equal(continuous.values[:, 0, :4], binned.values[:, 0, :4])
    single = xr.DataArray(np.full_like(strata, 2), dims=("y", "x"))  # measured centres: one class present
    np.testing.assert_array_equal(
        normalize(image, single, angles, stratum_table(strata, x, True), reference()).reflectance.values,
        normalize(image, single, angles, stratum_table(strata, x, False), reference()).reflectance.values)


@pytest.mark.parametrize("centres", [True, False])
def test_the_maps_nodata_is_no_class_in_an_interpolation_group(centres):
    # A class map whose nodata is 3, a class of the group: its pixels were interpolated (factors
    # 0.98-1.06, flagged no_class all the same) and, without given centres, they made class 3's
    # centre. As no class they are left as they are; the others interpolate between 1 and 2 only.
    image, angles, strata, x, _ = scene()
    classes = georeference(xr.DataArray(strata, dims=("y", "x"))).rio.write_nodata(3)
    image, angles = georeference(image), {name: georeference(layer) for name, layer in angles.items()}
    table = stratum_table(strata, x, True, centres=centres)
    corrected = normalize(image, classes, angles, table, reference())
    nodata = strata == 3
    np.testing.assert_array_equal(corrected.reflectance.values[:, nodata], image.values[:, nodata])
    assert (corrected.qa.values[nodata] == 2).all()  # no_class
    two = table.without_class(3)
    others = normalize(image, classes.where(~nodata, 0).astype(np.uint8), angles, two, reference()).reflectance
    np.testing.assert_allclose(corrected.reflectance.values[:, ~nodata], others.values[:, ~nodata], rtol=1e-12)


def test_a_group_of_equal_shapes_with_bad_bands_is_one_group():
    # w, n, k equal in every class, NaN in the bad band for every class: NaN != NaN refused the group.
    image, angles, strata, _, _ = scene(rows=4, columns=6)
    classes = [{"id": k, "name": f"t{k}", "model": "torrance_sparrow", "wavelengths": [600.0, 900.0],
                "bad_bands": [[540.0, 560.0]], "params": {"t0": [0.02 * k, 0.03 * k], "t1": [0.1, 0.2], "w": 0.05,
                                                          "n": 1.5, "k": 0.0}} for k in (1, 2, 3)]
    table = ParameterTable.from_dict({"classes": classes, "ndvi_interpolation": {"classes": [1, 2, 3]}})
    corrected = normalize(image, xr.DataArray(strata, dims=("y", "x")), angles, table, reference()).reflectance
    assert np.isfinite(corrected.values[1:]).all() and not np.array_equal(corrected.values[1:], image.values[1:])
    np.testing.assert_array_equal(corrected.values[0], image.values[0])  # the bad band, passed through


# ------------------------------------------------------------------------- the table
def test_table_round_trip_and_errors():
    image, angles, strata, x, _ = scene(rows=4, columns=6)
    table = stratum_table(strata, x, True, centres=True)
    again = ParameterTable.from_yaml_text(table.to_yaml_text())
    assert again.ndvi_interpolation == table.ndvi_interpolation
    assert table.without_class(3).ndvi_interpolation.classes == [1, 2]
    assert table.without_class(3).without_class(2).ndvi_interpolation is None
    base = stratum_table(strata, x, False).to_dict()
    for bad, words in (({"classes": [1, 4]}, "not in the table"), ({"classes": [1]}, "at least 2"),
                       ({"classes": [1, 2], "centres": [0.5, 0.2]}, "strictly increasing"),
                       ({"classes": [1, 2], "centres": [0.5]}, "one NDVI centre per class")):
        with pytest.raises(ParameterError, match=words):
            ParameterTable.from_dict({**base, "ndvi_interpolation": bad})


def test_different_shape_parameters_are_refused():
    image, angles, strata, _, _ = scene(rows=4, columns=6)
    classes = [{"id": k, "name": f"t{k}", "model": "torrance_sparrow",
                "params": {"t0": 0.02, "t1": 0.2, "w": w, "n": 1.5, "k": 0.0}} for k, w in ((1, 0.03), (2, 0.05))]
    table = ParameterTable.from_dict({"classes": classes, "ndvi_interpolation": {"classes": [1, 2]}})
    with pytest.raises(ParameterError, match="shape parameters"):
        normalize(image, xr.DataArray(strata, dims=("y", "x")), angles, table, reference())
    kernel = stratum_table(strata, np.full(strata.shape, 0.4), True)
    changed = kernel.with_class({"id": 2, "name": "flat", "model": "lambertian", "params": {"t0": 0.1}})
    with pytest.raises(ParameterError, match="share one model"):
        normalize(image, xr.DataArray(strata, dims=("y", "x")), angles, changed, reference())


# ------------------------------------------------------------------------- the command line
def test_cli_correct_with_an_interpolated_table_matches_the_library(tmp_path):
    """``brdfcorr correct`` with a table holding ``ndvi_interpolation`` (centres measured on the
    image, in chunks): the library's numbers, and the block kept in the provenance tag."""
    image, angles, strata, x, _ = scene(rows=40, columns=48)
    layers = {"reflectance": georeference(image.astype(np.float32).assign_coords(band=[1, 2, 3]).assign_attrs(
        long_name=tuple(f"{w:g} nm" for w in WAVELENGTHS))),
        "classes": georeference(xr.DataArray(strata, dims=("y", "x")))}
    layers.update({name: georeference(angles[name].astype(np.float32)) for name in ("sza", "saa", "vza", "vaa")})
    paths = write_scene(tmp_path, layers)
    table = stratum_table(strata, x, True)
    table.save(tmp_path / "params.yaml")
    output = tmp_path / "out.tif"
    result = CliRunner().invoke(main, ["correct", str(paths["image"]), "--angles", str(paths["angles"]),
                                       "--classes", str(paths["classes"]), "--params", str(tmp_path / "params.yaml"),
                                       "--ref-sza", "40", "-o", str(output), "--chunk", "16"],
                                catch_exceptions=False)
    assert result.exit_code == 0, result.output
    expected = normalize(layers["reflectance"], layers["classes"], {k: layers[k] for k in ("sza", "saa", "vza", "vaa")},
                         table, reference()).reflectance
    with rasterio.open(output) as written:
        np.testing.assert_allclose(written.read(), expected.values, rtol=1e-6)
        content = ParameterTable.from_dict(json.loads(written.tags()["brdf_parameter_table_content"]))
    assert content.ndvi_interpolation == table.ndvi_interpolation
