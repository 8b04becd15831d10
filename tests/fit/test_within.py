"""Free levels (fixed effects): the within transformation, the restored constant, the fit that
tells BRDF from land cover where the same ground is seen more than once (issue 37)."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from brdfcorr.errors import ParameterError
from brdfcorr.fit import ClassModels, Sampling, fit_classes, solver
from brdfcorr.fit.classes import ClassFitWarning, ClassSamples, GuardRails, fit_one_class
from brdfcorr.fit.sampling import sample_classes
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.fit.within import Levels, cluster_mean_variance, restored_constant
from brdfcorr.geometry import relative_azimuth
from brdfcorr.models import get_model

RTLSR = get_model("ross_thick_li_sparse")
TRUTH = {"f_iso": 0.1, "f_vol": 0.06, "f_geo": 0.015}


def test_one_factor_demeaning_leaves_every_group_mean_zero():
    rng = np.random.default_rng(0)
    codes = rng.integers(0, 7, 200)
    values = rng.normal(size=(200, 3))
    within = Levels.from_labels(codes).demean(values)
    for group in np.unique(codes):
        np.testing.assert_allclose(within[codes == group].mean(axis=0), 0.0, atol=1e-12)
    # The deviations from the group means themselves (an independent computation).
    means = np.array([values[codes == c].mean(axis=0) for c in range(7)])
    np.testing.assert_allclose(within, values - means[codes], atol=1e-12)


def test_two_factor_demeaning_equals_least_squares_with_dummies():
    """Two-way within transformation = residuals of a regression on both factors' dummies
    (Frisch-Waugh-Lovell), here on an unbalanced panel where one sweep is not enough."""
    rng = np.random.default_rng(1)
    pixel, scene = rng.integers(0, 12, 150), rng.integers(0, 4, 150)
    values = rng.normal(size=150)
    dummies = np.column_stack([pixel == p for p in range(12)] + [scene == s for s in range(1, 4)]).astype(float)
    coefficients, *_ = np.linalg.lstsq(dummies, values, rcond=None)
    within = Levels.from_labels(pixel, scene).demean(values[:, None])[:, 0]
    np.testing.assert_allclose(within, values - dummies @ coefficients, atol=1e-8)


def test_restored_constant_gives_the_fit_the_data_mean():
    # f = t0 + sum p_j B_j at the means: t0 = (mean f - sum p_j mean B_j) / mean B_0.
    value = restored_constant(np.array([0.3]), np.array([0.5, 2.0]), np.array([[0.1], [0.05]]), 1.0)
    assert value == pytest.approx(0.3 - 0.05 - 0.1)


def test_cluster_mean_variance_is_the_cr1_formula():
    values = np.array([[1.0], [3.0], [2.0], [6.0]])
    clusters = np.array([0, 0, 1, 1])
    # cluster sums of deviations from the mean 3: (-2 + 0) and (-1 + 3); G / (G - 1) = 2.
    assert cluster_mean_variance(values, clusters)[0] == pytest.approx(2 * (4 + 4) / 16)


def _confounded_views(rng, pixels=2000, views=5, noise=0.01):
    """Pixels seen ``views`` times, whose brightness (cover) follows their first view zenith: a
    pooled fit over one view reads the cover as BRDF."""
    sza = rng.uniform(25, 45, (pixels, views))
    vza = rng.uniform(0, 40, (pixels, views))
    phi = rng.uniform(0, 180, (pixels, views))
    cover = 1 + 0.5 * (vza[:, :1] / 40 - 0.5) + 0.1 * rng.standard_normal((pixels, 1))
    brdf = RTLSR(sza, vza, phi, **TRUTH) * cover * (1 + noise * rng.standard_normal((pixels, views)))
    return sza, vza, phi, brdf, np.repeat(np.arange(pixels)[:, None], views, axis=1), float(cover.mean())


def test_free_levels_recover_the_shape_a_pooled_fit_reads_from_the_cover():
    sza, vza, phi, brdf, pixel, mean_cover = _confounded_views(np.random.default_rng(2))
    pooled = fit_class_samples(RTLSR, sza[:, 0], vza[:, 0], phi[:, 0], brdf[:, :1])
    within = fit_class_samples(RTLSR, sza.ravel(), vza.ravel(), phi.ravel(), brdf.reshape(-1, 1),
                               levels=Levels.from_labels(pixel.ravel()))
    for name, truth in TRUTH.items():
        truth *= mean_cover  # the class's mean pixel
        value, error = within["params"][name][0], within["errors"][name][0]
        assert abs(value - truth) < 4 * error, name
    # The pooled fit of one view takes the cover's trend for volume scattering.
    ratio = pooled["params"]["f_vol"][0] / pooled["params"]["f_iso"][0]
    assert abs(ratio - 0.6) > 20 * within["errors"]["f_vol"][0] / within["params"]["f_iso"][0]
    assert within["n_groups"] == 2000


def test_free_levels_errors_follow_the_scatter_over_seeds():
    """Pulls (fit - truth) / error over 60 seeds of the restored f_iso and of the ratios
    f_vol / f_iso and f_geo / f_iso (what a correction uses; their errors propagated from the
    joint covariance): standard deviation near 1 and mean near 0."""
    pulls = []
    for seed in range(60):
        sza, vza, phi, brdf, pixel, _ = _confounded_views(np.random.default_rng(100 + seed), pixels=150, views=3,
                                                           noise=0.03)
        result = fit_class_samples(RTLSR, sza.ravel(), vza.ravel(), phi.ravel(), brdf.reshape(-1, 1),
                                   levels=Levels.from_labels(pixel.ravel()))
        params, covariance, names = result["params"], result["covariance"][0], list(result["free"])
        iso = params["f_iso"][0]
        row = [(iso - TRUTH["f_iso"]) / result["errors"]["f_iso"][0]]  # the expected cover is 1
        for name in ("f_vol", "f_geo"):
            ratio = params[name][0] / iso
            gradient = np.zeros(len(names))
            gradient[names.index(name)], gradient[names.index("f_iso")] = 1 / iso, -ratio / iso
            row.append((ratio - TRUTH[name] / TRUTH["f_iso"]) / np.sqrt(gradient @ covariance @ gradient))
        pulls.append(row)
    spread, mean = np.std(pulls, axis=0), np.mean(pulls, axis=0)
    assert np.all((spread > 0.75) & (spread < 1.3)), spread
    assert np.all(np.abs(mean) < 0.35), mean


def test_free_levels_are_exact_for_a_multiplicative_level_without_noise():
    """f = s_n g: the shape and the ratios come out exact however the levels follow the view
    (the within fit at the model's level of each group, brdfcorr.fit.within)."""
    ts = get_model("torrance_sparrow")
    rng = np.random.default_rng(3)
    sza, vza, phi = rng.uniform(25, 45, (1000, 4)), rng.uniform(0, 40, (1000, 4)), rng.uniform(0, 180, (1000, 4))
    level = 1 + 0.5 * (vza[:, :1] / 40 - 0.5)
    truth = {"t0": 0.05, "t1": 0.3, "w": 0.08, "n": 1.6, "k": 0.25}
    brdf = ts(sza, vza, phi, **truth) * level
    pixel = np.repeat(np.arange(1000)[:, None], 4, axis=1)
    result = fit_class_samples(ts, sza.ravel(), vza.ravel(), phi.ravel(), brdf.reshape(-1, 1),
                               levels=Levels.from_labels(pixel.ravel()))
    assert result["params"]["w"][0] == pytest.approx(0.08, rel=1e-3)
    assert result["params"]["n"][0] == pytest.approx(1.6, rel=1e-3)
    ratio = result["params"]["t1"][0] / result["params"]["t0"][0]
    assert ratio == pytest.approx(6.0, rel=1e-3)


def _two_lines_of_levelled_pixels(pixels=2000, seed=4):
    """Noise-free RTLSR (float64) of pixels seen twice, by two lines with the sun at 30 and 52 deg
    on opposite sides of the principal plane, each pixel with its own multiplicative level (cover),
    which follows the first view zenith."""
    rng = np.random.default_rng(seed)
    sza = np.column_stack([np.full(pixels, 30.0), np.full(pixels, 52.0)])
    vza = rng.uniform(0, 40, (pixels, 2))
    phi = np.column_stack([rng.uniform(0, 60, pixels), rng.uniform(120, 180, pixels)])
    level = 1 + 0.5 * (vza[:, :1] / 40 - 0.5) + 0.3 * rng.uniform(-1, 1, (pixels, 1))
    brdf = RTLSR(sza, vza, phi, **TRUTH) * level
    return sza.ravel(), vza.ravel(), phi.ravel(), brdf.reshape(-1, 1), np.repeat(np.arange(pixels), 2)


def test_free_levels_iterate_to_the_exact_shape_without_noise():
    """The repeated fit is a fixed-point iteration whose fixed point, without noise, is the truth
    (brdfcorr.fit.within): iterated to LEVEL_TOLERANCE (1e-7) in the levels it recovers the
    ratios f_vol/f_iso = 0.6 and f_geo/f_iso = 0.15 to far better than 1e-6 (three fixed
    repetitions, the old rule, left them 1e-4 off)."""
    sza, vza, phi, brdf, pixel = _two_lines_of_levelled_pixels()
    result = fit_class_samples(RTLSR, sza, vza, phi, brdf, levels=Levels.from_labels(pixel))
    params = result["params"]
    assert params["f_vol"][0] / params["f_iso"][0] == pytest.approx(0.6, rel=1e-6)
    assert params["f_geo"][0] / params["f_iso"][0] == pytest.approx(0.15, rel=1e-6)
    assert result["levels_converged"] and 1 <= result["level_iterations"] <= solver.MAX_LEVEL_ITERATIONS


def test_free_levels_that_do_not_converge_are_kept_and_said(monkeypatch):
    """A fit whose levels are still moving at the cap keeps its fit (close, if not exact) and
    says so: levels_converged False, a note and a ClassFitWarning naming the class."""
    sza, vza, phi, brdf, pixel = _two_lines_of_levelled_pixels(pixels=600)
    monkeypatch.setattr(solver, "MAX_LEVEL_ITERATIONS", 1)
    result = fit_class_samples(RTLSR, sza, vza, phi, brdf, levels=Levels.from_labels(pixel))
    assert not result["levels_converged"] and result["level_iterations"] is None
    samples = ClassSamples(sza, vza, phi, brdf, block=pixel // 50, group=pixel, scene=np.tile([0, 1], 600),
                           levels="pixel")
    with pytest.warns(ClassFitWarning, match=r"class 4 \(grass\): free levels did not converge"):
        fit = fit_one_class(4, "grass", RTLSR, samples, guard=GuardRails(min_samples=100))
    assert fit.status == "fitted"
    assert any("did not converge" in note for note in fit.notes)


def _stack(dates: int, shape=(40, 64), seed=0):
    """Images of one grid seen on ``dates`` dates from alternating sides, with a cover gradient
    east-west that a pooled fit over one date confounds with the view."""
    rng = np.random.default_rng(seed)
    ny, nx = shape
    coords = {"y": np.arange(ny), "x": np.arange(nx)}
    cover = (1 + 0.3 * np.linspace(-1, 1, nx))[None, :] * np.ones((ny, 1))
    images, angles, maps = [], [], []
    for date in range(dates):
        vza = np.abs(np.linspace(-30, 30, nx))[None, :] * np.ones((ny, 1))
        vaa = np.where((np.arange(nx) < nx // 2) ^ (date % 2 == 1), 270.0, 90.0)[None, :] * np.ones((ny, 1))
        sza, saa = np.full(shape, 30.0 + 4 * date), np.full(shape, 100.0)
        brdf = RTLSR(sza, vza, relative_azimuth(saa, vaa), **TRUTH) * cover
        reflectance = np.pi * brdf * (1 + 0.01 * rng.standard_normal(shape))
        images.append(xr.DataArray(reflectance[None], dims=("band", "y", "x"), coords=coords))
        angles.append(xr.Dataset({k: (("y", "x"), v) for k, v in {"sza": sza, "saa": saa, "vza": vza,
                                                                   "vaa": vaa}.items()}, coords=coords))
        maps.append(xr.DataArray(np.ones(shape, np.int32), dims=("y", "x"), coords=coords))
    return images, maps, angles


def test_pixel_levels_sample_whole_pixels_on_one_grid():
    images, maps, angles = _stack(3)
    samples = sample_classes(images, maps, angles, sampling=Sampling(levels="pixel", max_samples=900))[1]
    assert samples.levels == "pixel"
    assert samples.theta_i.size <= 900
    labels, counts = np.unique(samples.group, return_counts=True)
    assert np.all(counts == 3)  # every date of each sampled pixel
    for label in labels[:20]:  # a pixel's views lie in one block and come from three scenes
        views = samples.group == label
        assert np.unique(samples.block[views]).size == 1
        assert sorted(samples.scene[views]) == [0, 1, 2]


def test_levels_auto_frees_pixels_of_a_stack_and_pools_a_single_scene():
    images, maps, angles = _stack(2)
    stack = fit_classes(images, maps, angles, ClassModels("ross_thick_li_sparse"), wavelengths=[650.0])
    single = fit_classes(images[:1], maps[:1], angles[:1], ClassModels("ross_thick_li_sparse"), wavelengths=[650.0])
    assert stack.fits[0].levels == "pixel" and stack.fits[0].n_groups > 0
    assert single.fits[0].levels == "pooled" and single.fits[0].n_groups is None
    assert stack.report()[0]["levels"] == "pixel"


def test_pixel_levels_refused_without_a_shared_grid():
    images, maps, angles = _stack(1)
    with pytest.raises(ParameterError, match="several scenes on one grid"):
        sample_classes(images, maps, angles, sampling=Sampling(levels="pixel"))
    with pytest.raises(ParameterError, match="divisor of the block size"):
        sample_classes(images, maps, angles, sampling=Sampling(levels="patch", patch_size=5, block_size=32))


def test_patches_of_one_flight_line_fail_the_spread_guard_rail():
    """Neighbouring pixels of one line differ in view zenith by a fraction of a degree: their
    differences carry no BRDF, and the guard rail says so in its own words."""
    images, maps, angles = _stack(1)
    with pytest.warns(UserWarning, match="geometry spread within each patch"):
        result = fit_classes(images, maps, angles, ClassModels("ross_thick_li_sparse"), wavelengths=[650.0],
                             sampling=Sampling(levels="patch", patch_size=4, block_size=8))
    assert result.fits[0].status == "uncorrected"


def test_a_time_cube_is_fitted_as_its_dates():
    import brdfcorr  # noqa: F401  (registers the .brdf accessor)

    images, maps, angles = _stack(3)
    by_list = fit_classes(images, maps, angles, ClassModels("ross_thick_li_sparse"), wavelengths=[650.0])
    cube, angle_cube = xr.concat(images, dim="time"), xr.concat(angles, dim="time")
    by_cube = cube.brdf.fit_classes(maps[0], angle_cube, wavelengths=[650.0])
    assert by_cube.fits[0].levels == "pixel"
    for name, values in by_list.fits[0].params.items():
        np.testing.assert_allclose(by_cube.fits[0].params[name], values)


def test_a_time_cubes_angles_are_its_dates_by_label():
    import pandas as pd

    import brdfcorr  # noqa: F401  (registers the .brdf accessor)

    images, maps, angles = _stack(3)
    dates = pd.Index(pd.date_range("2024-06-01", periods=3), name="time")
    cube, angle_cube = xr.concat(images, dim=dates), xr.concat(angles, dim=dates)
    in_order = cube.brdf.fit_classes(maps[0], angle_cube, wavelengths=[650.0])
    # The angles in reverse order, and a cube of two of the dates: each date still takes its own.
    reversed_angles = angle_cube.isel(time=[2, 1, 0])
    assert cube.brdf.fit_classes(maps[0], reversed_angles, wavelengths=[650.0]).table == in_order.table
    two = cube.isel(time=[0, 2]).brdf.fit_classes(maps[0], reversed_angles, wavelengths=[650.0])
    expected = fit_classes([images[0], images[2]], [maps[0]] * 2, [angles[0], angles[2]],
                           ClassModels("ross_thick_li_sparse"), wavelengths=[650.0])
    for name, values in expected.fits[0].params.items():
        np.testing.assert_allclose(two.fits[0].params[name], values)


def test_cli_fits_a_stack_of_dates_with_each_pixels_level_free(tmp_path):
    from click.testing import CliRunner

    from brdfcorr.cli import main

    images, maps, angles = _stack(2, shape=(48, 64))
    arguments = []
    for date, (image, class_map, angle_set) in enumerate(zip(images, maps, angles)):
        transform = {"crs": "EPSG:32632"}
        paths = [tmp_path / f"{stem}{date}.tif" for stem in ("image", "classes", "angles")]
        image.rio.write_crs(transform["crs"]).rio.to_raster(paths[0])
        class_map.rio.write_crs(transform["crs"]).rio.to_raster(paths[1])
        stacked = angle_set[["sza", "saa", "vza", "vaa"]].to_array("band").rio.write_crs(transform["crs"])
        stacked.attrs["long_name"] = ("sza", "saa", "vza", "vaa")
        stacked.rio.to_raster(paths[2])
        arguments += [str(paths[0]), "--classes", str(paths[1]), "--angles", str(paths[2])]
    result = CliRunner().invoke(main, ["fit-classes", *arguments, "--model", "ross_thick_li_sparse",
                                       "--block-size", "8", "-o", str(tmp_path / "table.yaml")])
    assert result.exit_code == 0, result.output
    assert "free levels per pixel" in result.output


def test_auto_pools_dates_whose_views_of_each_pixel_are_alike():
    """Two dates on one grid seen from the same geometry (one orbit, one time of day): nothing
    differs within a pixel, so auto fits the class pooled and says so."""
    images, maps, angles = _stack(1)
    result = fit_classes(images * 2, maps * 2, angles * 2, ClassModels("ross_thick_li_sparse"), wavelengths=[650.0])
    fit = result.fits[0]
    assert fit.levels == "pooled" and fit.status == "fitted"
    assert any("fitted pooled" in note for note in fit.notes)


def test_auto_with_free_levels_scores_the_true_model_on_held_out_differences():
    """The held-out predictions of each pixel's relative views are compared in the same units as
    the target: the true model (RTLSR) explains nearly all of them."""
    images, maps, angles = _stack(4)
    fit = fit_classes(images, maps, angles, ClassModels("auto"), wavelengths=[650.0]).fits[0]
    assert fit.levels == "pixel"
    assert fit.model_choice.score_of("ross_thick_li_sparse").heldout_r2 > 0.95
