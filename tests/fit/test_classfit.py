"""Class-pooled fitting from imagery (issue 6): retrieval, error calibration, guard rails."""

import math
import warnings

import numpy as np
import pytest
import xarray as xr

from brdfcorr.correction import normalize
from brdfcorr.fit.classes import (
    ClassFitWarning,
    ClassModels,
    GuardRails,
    Sampling,
    fit_class_samples,
    fit_classes,
    sample_classes,
)
from brdfcorr.models import empirical, torrance_sparrow
from brdfcorr.params import ParameterTable
from brdfcorr.testing import render, synthetic_classes

WAVELENGTHS = [480.0, 560.0, 660.0, 830.0]
TRUTH = ParameterTable(
    classes=[
        # Paper 003, Table 1 roof tile shape; spectral intensities made up for the test.
        {"id": 1, "name": "roof_tile", "model": "torrance_sparrow", "wavelengths": WAVELENGTHS,
         "params": {"t0": [0.015, 0.02, 0.03, 0.035], "t1": [0.15, 0.18, 0.22, 0.25],
                    "w": 0.0362, "n": 1.77, "k": 0.25}},
        {"id": 2, "name": "grass", "model": "empirical", "wavelengths": WAVELENGTHS,
         "params": {"a": [0.01, 0.02, 0.012, 0.06], "b": 1.0, "c": 0.03,
                    "t0": [0.01, 0.03, 0.015, 0.15]}},
    ]
)


def airborne_line(ny=100, nx=160, seed=0, albedo_spread=0.05, noise=0.005, vza_max=40.0):
    """A wide field-of-view line with the sun across track (saa 95 deg): backscatter on one side,
    forward scatter on the other. Reflectance = pi * f * albedo * (1 + noise)."""
    rng = np.random.default_rng(seed)
    cols = np.linspace(-1, 1, nx)[None, :]
    angles = {
        "sza": np.broadcast_to(np.linspace(35, 45, ny)[:, None], (ny, nx)).copy(),
        "saa": np.full((ny, nx), 95.0),
        "vza": np.broadcast_to(vza_max * np.abs(cols), (ny, nx)).copy(),
        "vaa": np.broadcast_to(np.where(cols < 0, 270.0, 90.0), (ny, nx)).copy(),
    }
    classes = synthetic_classes(ny, nx, ids=(1, 2), seed=seed)
    albedo = rng.normal(1.0, albedo_spread, (ny, nx))
    cube = render(TRUTH, classes, **angles, wavelengths=WAVELENGTHS, brightness=math.pi * albedo)
    cube *= 1 + noise * rng.standard_normal(cube.shape)
    coords = {"y": np.arange(ny), "x": np.arange(nx)}
    image = xr.DataArray(
        cube, dims=("band", "y", "x"),
        coords={**coords, "band": np.arange(1, 5), "wavelength": ("band", WAVELENGTHS)},
    )
    angle_set = xr.Dataset({k: (("y", "x"), v) for k, v in angles.items()}, coords=coords)
    return image, xr.DataArray(classes, dims=("y", "x"), coords=coords), angle_set


@pytest.fixture(scope="module")
def fitted():
    image, classes, angles = airborne_line()
    result = fit_classes(
        image, classes, angles,
        ClassModels("torrance_sparrow", class_models={2: "empirical"}, names={1: "roof_tile", 2: "grass"}),
    )
    return image, classes, angles, result


def test_retrieved_parameters_agree_with_truth_within_errors(fitted):
    *_, result = fitted
    for fit in result.fits:
        assert fit.status == "fitted", fit.reasons
        truth = TRUTH[fit.class_id].band_values(WAVELENGTHS)
        for name, values in fit.params.items():
            errors = fit.errors[name]
            free = errors > 0
            # Fixed k equals its truth exactly; every free value within 4 sigma (16 values, seeded).
            np.testing.assert_allclose(values[~free], truth[name][~free])
            pulls = (values[free] - truth[name][free]) / errors[free]
            assert np.all(np.abs(pulls) < 4), (fit.name, name, pulls)
        assert np.median(fit.r2) > 0.5


def test_shape_errors_are_calibrated_over_seeds():
    # The reported 1-sigma errors must describe the scatter of the estimates: over independent
    # noise realizations the pulls (estimate - truth) / error have a standard deviation near 1
    # (0.5-1.6 with 12 realizations, allowing for the sandwich estimator's conservatism).
    rng = np.random.default_rng(42)
    pulls = []
    for _ in range(12):
        n = 4000
        sza, vza = rng.uniform(30, 50, n), rng.uniform(0, 40, n)
        phi = np.where(rng.random(n) < 0.5, rng.uniform(150, 180, n), rng.uniform(0, 30, n))
        a, t0 = np.array([0.1, 0.2, 0.3]), np.array([0.01, 0.02, 0.05])
        f = empirical(sza[:, None], vza[:, None], phi[:, None], a=a, b=1.0, c=0.05, t0=t0)
        y = f * rng.normal(1, 0.1, (n, 1)) * (1 + 0.01 * rng.standard_normal(f.shape))
        result = fit_class_samples("empirical", sza, vza, phi, y)
        pulls.append((result["params"]["c"][0] - 0.05) / result["errors"]["c"][0])
    assert 0.5 < np.std(pulls) < 1.6
    assert abs(np.mean(pulls)) < 1.0


def test_correcting_with_fitted_parameters_removes_the_gradient_like_the_truth(fitted):
    image, classes, angles, result = fitted
    kwargs = dict(reference={"sza": 40.0, "vza": 0.0, "raa": 0.0}, limits=None)
    layers = {k: angles[k] for k in ("sza", "saa", "vza", "vaa")}
    observed = image.sel(band=1).where(classes == 1)
    with_fit = normalize(image, classes, layers, result.table, **kwargs).reflectance
    with_truth = normalize(image, classes, layers, TRUTH, **kwargs).reflectance

    def across_track_spread(cube):
        # Relative spread of the column means of the roof-tile class in band 1.
        columns = cube.where(classes == 1).mean("y")
        return float(columns.std() / columns.mean())

    before = across_track_spread(observed)
    after_fit = across_track_spread(with_fit.sel(band=1))
    after_truth = across_track_spread(with_truth.sel(band=1))
    assert before > 0.15  # there is a strong gradient to remove
    assert after_fit < 0.25 * before
    assert after_fit == pytest.approx(after_truth, abs=0.01)


def test_table_round_trips_and_carries_wavelengths(fitted, tmp_path):
    *_, result = fitted
    path = result.table.save(tmp_path / "fitted.yaml")
    loaded = ParameterTable.load(path)
    assert loaded.class_ids == (1, 2)
    assert loaded[1].wavelengths == WAVELENGTHS
    assert loaded[1].params["k"] == 0.25
    report = result.report()
    assert {entry["name"] for entry in report} == {"roof_tile", "grass"}
    assert report[0]["n_samples"] > 1000 and report[0]["vza_spread_deg"] > 30


def test_guard_rails_fall_back_or_leave_uncorrected_and_say_so():
    image, classes, angles = airborne_line(ny=40, nx=60, vza_max=40.0)
    # Class 2 only in a narrow strip near nadir: view zenith spread far below 10 deg.
    narrow = xr.where(np.abs(angles["vza"]) < 3, classes, 1)
    with pytest.warns(ClassFitWarning, match=r"class 2 \(class_2\): .*view zenith spread"):
        result = fit_classes(image, narrow, angles, "empirical")
    fits = {fit.class_id: fit for fit in result.fits}
    assert fits[2].status == "uncorrected" and 2 not in result.table
    assert fits[1].status == "fitted" and 1 in result.table

    with pytest.warns(ClassFitWarning, match="using built-in material 'roof_tile'"):
        result = fit_classes(
            image, narrow, angles, ClassModels("empirical", fallback="roof_tile"),
            guard=GuardRails(min_samples=10**6),
        )
    assert all(fit.status == "fallback" for fit in result.fits)
    assert result.table[1].model == "torrance_sparrow" and result.table[1].params["w"] == 0.0362


@pytest.mark.parametrize("spread", [9.96, 9.999, 0.04])
def test_a_spread_below_the_guard_rail_never_reads_as_the_limit(spread):
    # Rounded to one decimal, 9.96 deg read "10.0 deg < 10 deg".
    text = GuardRails(min_vza_spread=10.0).spread_short(spread)
    shown = float(text.split()[0])
    assert shown < 10.0 and shown <= spread and text.endswith("< 10 deg")


def test_classes_fitted_in_a_process_pool_give_the_same_table_and_warnings():
    # `fit-classes --workers N`: each class's fit is independent and the same computation in a
    # worker process; its warnings, recorded there, are given here in the classes' order. A model
    # object from the registry travels by its name (some kernels are closures, which do not pickle).
    import concurrent.futures
    import multiprocessing

    from brdfcorr.models import get_model

    image, classes, angles = airborne_line(ny=40, nx=60, vza_max=40.0)
    narrow = xr.where(np.abs(angles["vza"]) < 3, classes, 1)  # class 2 fails its view zenith spread
    models = ClassModels("empirical", class_models={2: get_model("ross_thick_li_sparse")})
    with warnings.catch_warnings(record=True) as alone_warnings:
        warnings.simplefilter("always", ClassFitWarning)
        alone = fit_classes(image, narrow, angles, models)
    with warnings.catch_warnings(record=True) as pooled_warnings, \
            concurrent.futures.ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("spawn")) as pool:
        warnings.simplefilter("always", ClassFitWarning)
        pooled = fit_classes(image, narrow, angles, models, executor=pool)
    assert pooled.table.to_dict() == alone.table.to_dict() and pooled.table.class_ids == (1,)
    assert [fit.summary() for fit in pooled.fits] == [fit.summary() for fit in alone.fits]
    messages = [str(w.message) for w in alone_warnings if w.category is ClassFitWarning]
    assert messages and [str(w.message) for w in pooled_warnings if w.category is ClassFitWarning] == messages


def test_sampling_is_reproducible_capped_and_lazy_safe():
    image, classes, angles = airborne_line(ny=40, nx=60)
    first = sample_classes(image, classes, angles, sampling=Sampling(max_samples=300, seed=3))
    again = sample_classes(image.chunk({"y": 16}), classes, angles, sampling=Sampling(max_samples=300, seed=3))
    other = sample_classes(image, classes, angles, sampling=Sampling(max_samples=300, seed=4))
    for class_id in (1, 2):
        assert first[class_id].brdf.shape == (300, 4)
        np.testing.assert_array_equal(first[class_id].brdf, again[class_id].brdf)
        assert not np.array_equal(first[class_id].theta_r, other[class_id].theta_r)
    # Two scenes pool their pixels: the cap applies to the union.
    pooled = sample_classes([image, image], [classes, classes], [angles, angles], sampling=Sampling(max_samples=10**6, levels="pooled"))
    single = sample_classes(image, classes, angles, sampling=Sampling(max_samples=10**6))
    assert pooled[1].brdf.shape[0] == 2 * single[1].brdf.shape[0]


def test_ts_fit_of_noise_free_data_is_exact():
    # Closed-form check of the variable-projection solver: noise-free data are reproduced.
    rng = np.random.default_rng(0)
    sza, vza, phi = rng.uniform(20, 60, 3000), rng.uniform(0, 60, 3000), rng.uniform(0, 180, 3000)
    truth = dict(t0=np.array([0.02, 0.05]), t1=np.array([0.2, 0.4]), w=0.08, n=1.5, k=0.25)
    y = torrance_sparrow(sza[:, None], vza[:, None], phi[:, None], **truth)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = fit_class_samples("torrance_sparrow", sza, vza, phi, y)
    for name in ("w", "n"):
        assert result["params"][name][0] == pytest.approx(truth[name], rel=1e-4)
    np.testing.assert_allclose(result["params"]["t1"], truth["t1"], rtol=1e-3)
    np.testing.assert_allclose(result["r2"], 1.0, atol=1e-8)


def test_cli_fit_classes_writes_table_report_and_plots(tmp_path):
    import json

    import matplotlib.image
    from click.testing import CliRunner

    from brdfcorr.cli import main
    from brdfcorr.testing import georeference, write_scene

    image, classes, angles = airborne_line(ny=64, nx=96)
    classes[:4] = 255  # the class map's nodata (write_scene): "no class", never a class 255
    # Band descriptions "480 nm", ... carry the wavelengths in the GeoTIFF (DESIGN.md).
    image.attrs["long_name"] = tuple(f"{w:g} nm" for w in WAVELENGTHS)
    scene = {
        "reflectance": georeference(image.drop_vars(["x", "y"])),
        "classes": georeference(classes.drop_vars(["x", "y"]).astype(np.uint8)),
        **{k: georeference(angles[k].drop_vars(["x", "y"])) for k in ("sza", "saa", "vza", "vaa")},
    }
    paths = write_scene(tmp_path / "scene", scene)
    inputs = {p: p.read_bytes() for p in paths.values()}
    out = tmp_path / "out"
    result = CliRunner().invoke(main, [
        "fit-classes", str(paths["image"]), "--angles", str(paths["angles"]),
        "--classes", str(paths["classes"]), "--class-model", "2=empirical", "--name", "1=roof_tile",
        "--name", "2=grass", "-o", str(out / "params.yaml"), "--report", str(out / "report.json"),
        "--plot-dir", str(out / "plots"),
    ])
    assert result.exit_code == 0, result.output
    table = ParameterTable.load(out / "params.yaml")
    assert table.class_ids == (1, 2)
    assert table[1].name == "roof_tile" and table[2].model == "empirical"
    # Wavelengths from the image's band descriptions travel into the table.
    assert table[1].wavelengths == WAVELENGTHS
    report = json.loads((out / "report.json").read_text())["classes"]
    assert [entry["status"] for entry in report] == ["fitted", "fitted"]
    assert abs(report[0]["params"]["w"] - 0.0362) < 4 * report[0]["errors"]["w"]
    assert matplotlib.image.imread(out / "plots" / "class_1_roof_tile.png").shape[1] > 800
    assert all(p.read_bytes() == data for p, data in inputs.items())  # inputs untouched

    mismatch = CliRunner().invoke(main, [
        "fit-classes", str(paths["image"]), str(paths["image"]), "--angles", str(paths["angles"]),
        "--classes", str(paths["classes"]), "-o", str(out / "other.yaml"),
    ])
    assert mismatch.exit_code == 2
    assert "2 image(s), 1 --angles and 1 --classes" in mismatch.output
    assert not (out / "other.yaml").exists()


def _single_class_line(seed, texture_sigma, ny=90, nx=140):
    """One roof-tile class across a 40-deg swing of view zenith; albedo 10 % (std), either
    independent per pixel (texture_sigma 0) or smooth over a few pixels (a Gaussian filter)."""
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(seed)
    cols = np.linspace(-1, 1, nx)[None, :]
    angles = {"sza": np.full((ny, nx), 40.0), "saa": np.full((ny, nx), 95.0),
              "vza": np.broadcast_to(40 * np.abs(cols), (ny, nx)).copy(),
              "vaa": np.broadcast_to(np.where(cols < 0, 270.0, 90.0), (ny, nx)).copy()}
    noise = rng.standard_normal((ny, nx))
    if texture_sigma:
        noise = gaussian_filter(noise, texture_sigma)
    albedo = 1 + 0.1 * noise / noise.std()
    classes = np.ones((ny, nx), int)
    cube = render(TRUTH, classes, **angles, wavelengths=WAVELENGTHS, brightness=math.pi * albedo)
    coords = {"y": np.arange(ny), "x": np.arange(nx)}
    return (xr.DataArray(cube, dims=("band", "y", "x"), coords={**coords, "band": np.arange(1, 5)}),
            xr.DataArray(classes, dims=("y", "x"), coords=coords),
            xr.Dataset({k: (("y", "x"), v) for k, v in angles.items()}, coords=coords))


def test_block_robust_errors_grow_with_spatially_correlated_albedo():
    # Cluster-robust errors (spatial blocks) equal the independent-sample ones when the albedo is
    # independent from pixel to pixel, and are several times larger when it is smooth in space
    # (neighbouring pixels share their error, so there are fewer independent samples).
    def w_error(scene, block_size):
        return fit_classes(*scene, sampling=Sampling(block_size=block_size)).fits[0].errors["w"][0]

    independent = _single_class_line(1, texture_sigma=0)
    assert w_error(independent, 8) == pytest.approx(w_error(independent, 1), rel=0.3)
    smooth = _single_class_line(1, texture_sigma=2.0)
    assert w_error(smooth, 8) > 3 * w_error(smooth, 1)


def test_cli_fit_classes_reads_view_azimuths_from_the_sensor_with_the_flip(tmp_path):
    # The same line written twice, the second with each view azimuth as seen from the sensor
    # (vaa + 180): with --flip-view-azimuth its table is the first one's, as `correct` applies it.
    from click.testing import CliRunner

    from brdfcorr.cli import main
    from brdfcorr.testing import georeference, write_scene

    image, classes, angles = airborne_line(ny=48, nx=64)
    tables = []
    for name, turn, flags in (("plain", 0.0, []), ("from_sensor", 180.0, ["--flip-view-azimuth"])):
        scene = {"reflectance": georeference(image.drop_vars(["x", "y"])),
                 "classes": georeference(classes.drop_vars(["x", "y"]).astype(np.uint8)),
                 **{k: georeference(angles[k].drop_vars(["x", "y"])) for k in ("sza", "saa", "vza")},
                 "vaa": georeference(((angles["vaa"] + turn) % 360.0).drop_vars(["x", "y"]))}
        paths = write_scene(tmp_path / name, scene)
        output = tmp_path / f"{name}.yaml"
        result = CliRunner().invoke(main, ["fit-classes", str(paths["image"]), "--angles", str(paths["angles"]),
                                           "--classes", str(paths["classes"]), "-o", str(output), "--no-progress",
                                           *flags])
        assert result.exit_code == 0, result.output
        tables.append(ParameterTable.load(output))
    assert tables[0].class_ids == tables[1].class_ids and tables[0].class_ids
    for ours, theirs in zip(tables[1].classes, tables[0].classes):
        for name, values in ours.params.items():
            np.testing.assert_allclose(values, theirs.params[name], rtol=1e-5)
