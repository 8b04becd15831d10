"""Tests of the ``fit:`` provenance block of parameter tables (brdfcorr.params.FitRecord)."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from brdfcorr.errors import ParameterError
from brdfcorr.fit.measurements import MeasurementSelection
from brdfcorr.params import FitRecord, ParameterTable

# Two wavelengths, two fitted parameters (f_geo held fixed). Errors are sqrt(diag) by hand:
# sqrt(4e-4) = 0.02, sqrt(1e-4) = 0.01, sqrt(9e-4) = 0.03, sqrt(4e-4) = 0.02.
PER_WAVELENGTH = {
    "id": 2, "name": "grass", "model": "ross_thick_li_sparse", "wavelengths": [450, 850],
    "params": {"f_iso": [0.01, 0.14], "f_vol": [0.006, 0.11], "f_geo": 0.004},
    "fit": {
        "source": "brdfcorr fit-classes scene.tif --classes classes.tif",
        "parameters": ["f_iso", "f_vol"],
        "n": [100, 120], "chi2_dof": [1.0, 1.1], "r2": [0.9, 0.95],
        "errors": {"f_iso": [0.02, 0.03], "f_vol": [0.01, 0.02]},
        "covariance": [[[4e-4, 1e-5], [1e-5, 1e-4]], [[9e-4, -2e-5], [-2e-5, 4e-4]]],
    },
}
# Band-independent parameters: one matrix.
SINGLE = {
    "id": 1, "name": "roof_tile", "model": "torrance_sparrow",
    "params": {"t0": 0.0245, "t1": 0.20, "w": 0.0362, "n": 1.77, "k": 0.25},
    "fit": {
        "source": "brdfcorr fit tiles.csv --model torrance_sparrow",
        "parameters": ["t0", "t1"], "n": 57, "chi2_dof": 0.93, "r2": 0.98,
        "errors": {"t0": 0.002, "t1": 0.05},
        "covariance": [[4e-6, 3e-5], [3e-5, 2.5e-3]],
    },
}


def _table(*entries) -> ParameterTable:
    return ParameterTable.from_dict({"classes": [copy.deepcopy(e) for e in entries]}, "t.yaml")


def test_round_trip_through_yaml():
    table = _table(SINGLE, PER_WAVELENGTH)
    again = ParameterTable.from_yaml_text(table.to_yaml_text(), "again.yaml")
    assert again == table
    assert again[2].fit is not None and again[2].fit.per_wavelength
    assert again.to_dict()["classes"][0]["fit"]["parameters"] == ["t0", "t1"]


def test_round_trip_through_a_file(tmp_path):
    table = _table(SINGLE)
    assert ParameterTable.load(table.save(tmp_path / "t.yaml")) == table


def test_table_without_fit_is_unchanged():
    entry = {key: value for key, value in SINGLE.items() if key != "fit"}
    table = _table(entry)
    assert "fit" not in table.to_dict()["classes"][0]
    resolved = table.for_bands(n_bands=2)[1]
    assert resolved.covariance is None and resolved.covariance_names == ()


def test_numpy_covariance_is_accepted():
    fit = FitRecord(source="s", parameters=["t0"], n=3, chi2_dof=1.0, r2=0.5,
                    errors={"t0": 0.1}, covariance=np.array([[0.01]]))
    assert fit.covariance == [[0.01]]
    assert fit.matrices().shape == (1, 1, 1)


def test_interpolated_to_bands_like_the_parameters():
    # 650 nm is half way 450..850: every element is the mean of the two matrices (by hand).
    resolved = _table(PER_WAVELENGTH).for_bands(wavelengths=[450, 650, 850])[2]
    assert resolved.covariance_names == ("f_iso", "f_vol")
    expected = np.array([[[4e-4, 1e-5], [1e-5, 1e-4]],
                         [[6.5e-4, -0.5e-5], [-0.5e-5, 2.5e-4]],
                         [[9e-4, -2e-5], [-2e-5, 4e-4]]])
    np.testing.assert_allclose(resolved.covariance, expected, rtol=1e-12)
    np.testing.assert_allclose(resolved.params["f_iso"], [0.01, 0.075, 0.14])


def test_outside_wavelengths_follows_the_extrapolate_rule():
    table = _table(PER_WAVELENGTH)
    with pytest.raises(ParameterError, match=r"class 2 \(grass\).*900 nm"):
        table.for_bands(wavelengths=[900])
    resolved = table.for_bands(wavelengths=[400, 900], extrapolate=True)[2]
    np.testing.assert_allclose(resolved.covariance[0], PER_WAVELENGTH["fit"]["covariance"][0])
    np.testing.assert_allclose(resolved.covariance[1], PER_WAVELENGTH["fit"]["covariance"][1])


def test_single_matrix_applies_to_every_band():
    resolved = _table(SINGLE).for_bands(n_bands=4)[1]
    assert resolved.covariance.shape == (4, 2, 2)
    np.testing.assert_array_equal(resolved.covariance[3], SINGLE["fit"]["covariance"])


def test_per_band_matrices_without_wavelengths():
    entry = copy.deepcopy(PER_WAVELENGTH)
    del entry["wavelengths"]
    resolved = _table(entry).for_bands(n_bands=2)[2]
    np.testing.assert_array_equal(resolved.covariance, entry["fit"]["covariance"])
    with pytest.raises(ParameterError, match=r"class 2 \(grass\).*2 per-band values but the image has 3"):
        _table(entry).for_bands(n_bands=3)


def _set(path: str, value):
    def change(entry):
        *parents, key = path.split(".")
        target = entry["fit"]
        for parent in parents:
            target = target[parent]
        target[key] = value
    return change


@pytest.mark.parametrize(("base", "change", "message"), [
    (SINGLE, _set("errors.t0", 0.0021), r"class 1 \(roof_tile\): fit: errors.t0 = 0.0021 is not sqrt"),
    (SINGLE, _set("covariance", [[4e-6, 3e-5], [3.1e-5, 2.5e-3]]), r"fit: covariance: .*symmetric"),
    (SINGLE, _set("covariance", [[-4e-6, 0.0], [0.0, 2.5e-3]]), r"fit: covariance: the diagonal .* >= 0"),
    (SINGLE, _set("covariance", [[float("nan"), 0.0], [0.0, 2.5e-3]]), r"fit: covariance: .*finite"),
    (SINGLE, _set("covariance", [[4e-6]]), r"fit: covariance: expected 2 x 2 matrices"),
    (SINGLE, _set("parameters", ["t0", "t0"]), r"fit: parameters t0 are listed more than once"),
    (SINGLE, _set("n", [57]), r"fit: n: expected one number"),
    (SINGLE, _set("n", 0), r"fit: n: the number of samples must be >= 1"),
    (SINGLE, _set("errors", {"t0": 0.002}), r"fit: errors: expected one entry per fitted parameter \(t0, t1\)"),
    (SINGLE, _set("chi2", 1.0), r"class 1 \(roof_tile\): fit.chi2: unknown key; allowed keys: chi2_dof, "),
    (SINGLE, _set("n", True), r"fit.n: expected a number, got the boolean true"),
    (PER_WAVELENGTH, _set("r2", 0.9), r"class 2 \(grass\): fit: r2: expected a list of 2 values"),
    (PER_WAVELENGTH, _set("errors.f_vol", [0.01]), r"fit: errors.f_vol: expected 2 values"),
])
def test_invalid_fit_blocks_name_the_class_and_key(base, change, message):
    entry = copy.deepcopy(base)
    change(entry)
    with pytest.raises(ParameterError, match=message):
        _table(entry)


def test_fit_parameters_must_belong_to_the_model():
    entry = copy.deepcopy(SINGLE)
    entry["fit"].update(parameters=["t0", "f_iso"], errors={"t0": 0.002, "f_iso": 0.05})
    with pytest.raises(ParameterError, match=r"class 1 \(roof_tile\): fit.parameters: 'f_iso' not a parameter "
                                             r"of torrance_sparrow; its parameters: t0, t1, w, n, k"):
        _table(entry)


def test_matrix_count_must_match_the_wavelengths():
    entry = copy.deepcopy(PER_WAVELENGTH)
    entry["wavelengths"] = [450, 650, 850]
    entry["params"] = {"f_iso": [0.01, 0.05, 0.14], "f_vol": 0.01, "f_geo": 0.004}
    with pytest.raises(ParameterError, match=r"class 2 \(grass\): fit.covariance has 2 matrices but the class "
                                             r"has 3 wavelengths"):
        _table(entry)


def test_single_matrix_for_varying_parameters_is_an_error():
    entry = copy.deepcopy(PER_WAVELENGTH)
    entry["fit"].update(n=10, chi2_dof=1.0, r2=0.5, errors={"f_iso": 0.02, "f_vol": 0.01},
                        covariance=[[4e-4, 0.0], [0.0, 1e-4]])
    with pytest.raises(ParameterError, match=r"single matrix but f_iso, f_vol vary with wavelength"):
        _table(entry)


# --- fit and fit-classes write the block ------------------------------------------------------
def _goniometer_csv(directory, wavelengths=(None,)):
    """Roof tile measurements (paper 003, Table 1) with 2 % noise, at one or more wavelengths."""
    from brdfcorr.fit.synthetic import goniometer_angles, synthesize_measurements
    from brdfcorr.models.materials import load_material

    truth = load_material("roof_tile")
    lines = ["theta_i,theta_r,phi,brdf,sigma" + (",wavelength" if wavelengths[0] else "")]
    for seed, wavelength in enumerate(wavelengths):
        part = synthesize_measurements(truth.model, {**truth.params, "t0": 0.02 + 0.01 * seed},
                                       *goniometer_angles(), seed=seed, wavelength=wavelength)
        columns = [part.theta_i, part.theta_r, part.phi, part.brdf, part.sigma]
        columns += [part.wavelength] if wavelength else []
        lines += [",".join(f"{value:.10g}" for value in row) for row in zip(*columns)]
    path = directory / "tiles.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_goniometer_fit_writes_its_fit_block(tmp_path):
    from brdfcorr.tasks.goniometer import fit_measurement_file

    fit = fit_measurement_file(_goniometer_csv(tmp_path), "torrance_sparrow", fixed={"k": 0.25},
                               select=MeasurementSelection(min_phi=90))
    result = fit.results[None]
    entry = ParameterTable().with_class(fit.table_entry(1, "tiles"))[1]
    record = entry.fit
    assert record.source == "brdfcorr fit tiles.csv (torrance_sparrow; fixed k=0.25; phi >= 90)"
    assert record.parameters == ["t0", "t1", "w", "n"]  # k fixed: not listed
    np.testing.assert_array_equal(record.matrices()[0], 0.5 * (result.covariance + result.covariance.T))
    assert record.errors == pytest.approx({name: result.errors[name] for name in record.parameters}, rel=1e-12)
    assert record.n == fit.fitted.brdf.size == result.n_measurements
    assert record.chi2_dof == pytest.approx(result.chi2 / (record.n - 4))
    # R^2 computed here from the fitted measurements and the model's prediction.
    measured = fit.fitted.brdf
    predicted = result.predict(fit.fitted.theta_i, fit.fitted.theta_r, fit.fitted.phi)
    expected_r2 = 1 - np.sum((measured - predicted) ** 2) / np.sum((measured - measured.mean()) ** 2)
    assert record.r2 == pytest.approx(expected_r2, rel=1e-9)
    saved = ParameterTable(classes=[entry]).save(tmp_path / "table.yaml")
    assert ParameterTable.load(saved)[1] == entry


def test_spectral_goniometer_fit_has_one_matrix_per_wavelength(tmp_path):
    from brdfcorr.tasks.goniometer import fit_measurement_file

    fit = fit_measurement_file(_goniometer_csv(tmp_path, (450.0, 850.0)), "torrance_sparrow",
                               fixed={"k": 0.25}, select=MeasurementSelection(min_phi=90))
    table = ParameterTable().with_class(fit.table_entry(3, "tiles"))
    assert table[3].fit.per_wavelength and table[3].fit.n == [fit.results[450.0].n_measurements] * 2
    resolved = table.for_bands(wavelengths=[450.0, 650.0, 850.0])[3]
    low, high = fit.results[450.0].covariance, fit.results[850.0].covariance
    np.testing.assert_allclose(resolved.covariance[0], low, rtol=1e-12)
    np.testing.assert_allclose(resolved.covariance[1], 0.5 * (low + high), rtol=1e-9)  # half way
    np.testing.assert_allclose(resolved.covariance[2], high, rtol=1e-12)


def _scene(ny=48, nx=80, seed=0):
    """A wide field-of-view line of one roof-tile class (paper 003, Table 1 shape), four bands."""
    import math

    import xarray as xr

    from brdfcorr.testing import render

    wavelengths = [480.0, 560.0, 660.0, 830.0]
    truth = ParameterTable(classes=[{
        "id": 1, "name": "roof_tile", "model": "torrance_sparrow", "wavelengths": wavelengths,
        "params": {"t0": [0.015, 0.02, 0.03, 0.035], "t1": [0.15, 0.18, 0.22, 0.25],
                   "w": 0.0362, "n": 1.77, "k": 0.25}}])
    rng = np.random.default_rng(seed)
    cols = np.linspace(-1, 1, nx)[None, :]
    angles = {
        "sza": np.broadcast_to(np.linspace(35, 45, ny)[:, None], (ny, nx)).copy(),
        "saa": np.full((ny, nx), 95.0),
        "vza": np.broadcast_to(40.0 * np.abs(cols), (ny, nx)).copy(),
        "vaa": np.broadcast_to(np.where(cols < 0, 270.0, 90.0), (ny, nx)).copy(),
    }
    classes = np.ones((ny, nx), dtype=np.uint8)
    cube = render(truth, classes, **angles, wavelengths=wavelengths, brightness=np.full((ny, nx), math.pi))
    cube *= 1 + 0.03 * rng.standard_normal(cube.shape)  # 3 % multiplicative noise
    coords = {"y": np.arange(ny), "x": np.arange(nx)}
    image = xr.DataArray(cube, dims=("band", "y", "x"),
                         coords={**coords, "band": np.arange(1, 5), "wavelength": ("band", wavelengths)})
    return (image, xr.DataArray(classes, dims=("y", "x"), coords=coords),
            xr.Dataset({k: (("y", "x"), v) for k, v in angles.items()}, coords=coords))


def test_imagery_fit_writes_its_fit_block(tmp_path):
    from brdfcorr.fit.classes import ClassModels, fit_classes

    result = fit_classes(*_scene(), ClassModels(names={1: "roof_tile"})).with_source("test scene")
    fit, entry = result.fits[0], result.table[1]
    record = entry.fit
    assert fit.status == "fitted" and record.source == "test scene"
    assert record.parameters == ["t0", "t1", "w", "n"] == list(fit.free)  # shape and intensities jointly
    assert record.per_wavelength and len(record.covariance) == 4  # one matrix per band
    np.testing.assert_allclose(record.matrices(), fit.covariance, rtol=1e-12)
    for name in record.parameters:
        np.testing.assert_allclose(record.errors[name], fit.errors[name], rtol=1e-9)
    assert record.n == [fit.n_samples] * 4
    np.testing.assert_allclose(record.r2, fit.r2)
    np.testing.assert_allclose(record.chi2_dof, fit.rmse**2 * fit.n_samples / (fit.n_samples - 4))
    # The covariance resolves to the image's own bands unchanged (they are the table's wavelengths).
    resolved = result.table.for_bands(wavelengths=entry.wavelengths)[1]
    np.testing.assert_allclose(resolved.covariance, fit.covariance, rtol=1e-12)
    loaded = ParameterTable.load(result.table.save(tmp_path / "t.yaml"))
    assert loaded[1].fit == record


def test_fit_class_files_names_its_inputs(tmp_path):
    from brdfcorr.tasks.fit import SceneFiles, fit_class_files
    from brdfcorr.testing import georeference, write_scene

    image, classes, angles = _scene()
    image.attrs["long_name"] = tuple(f"{w:g} nm" for w in image.wavelength.values)
    paths = write_scene(tmp_path / "scene", {
        "reflectance": georeference(image.drop_vars(["x", "y"])),
        "classes": georeference(classes.drop_vars(["x", "y"])),
        **{k: georeference(angles[k].drop_vars(["x", "y"])) for k in ("sza", "saa", "vza", "vaa")},
    })
    fit = fit_class_files([SceneFiles(paths["image"], paths["classes"], paths["angles"])], "torrance_sparrow")
    record = fit.table[1].fit
    assert record.source == "brdfcorr fit-classes image.tif (classes classes.tif; model torrance_sparrow)"
    assert record.parameters == ["t0", "t1", "w", "n"]
