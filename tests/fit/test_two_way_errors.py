"""Two-way cluster-robust errors over pixels (or blocks) and scenes (issue 37; Cameron, Gelbach and
Miller 2011, J. Bus. Econ. Stat. 29(2), 238-249)."""

from __future__ import annotations

import numpy as np
import pytest

from brdfcorr.errors import ParameterError
from brdfcorr.fit import Sampling, fit_classes
from brdfcorr.fit.profile import _profile
from brdfcorr.fit.sandwich import _joint_covariance
from brdfcorr.fit.solver import fit_class_samples
from brdfcorr.fit.two_way import TwoWayClusters, clustered_covariance, nearest_psd
from brdfcorr.geometry import ScatteringGeometry
from brdfcorr.models import get_model

RTLSR = get_model("ross_thick_li_sparse")
WEIGHTS = np.array([0.05, 0.02, 0.01])  # f_iso, f_vol, f_geo [sr^-1]


def _panel(pixels=40, scenes=12, seed=0, scene_sigma=0.1, pixel_sigma=0.01, noise=0.01):
    """RTLSR samples of ``pixels`` pixels seen in each of ``scenes`` scenes: a relative error
    shared by a pixel's views, one shared by a scene's pixels (its calibration, growing with the
    view zenith, so that the intercept does not absorb it) and independent noise."""
    rng = np.random.default_rng(seed)
    pixel = np.repeat(np.arange(pixels), scenes)
    scene = np.tile(np.arange(scenes), pixels)
    sza, vza, phi = rng.uniform(20, 50, pixel.size), rng.uniform(0, 40, pixel.size), rng.uniform(0, 180, pixel.size)
    design = np.column_stack([np.broadcast_to(np.asarray(t, float), (pixel.size,)) for t in
                              RTLSR.terms(ScatteringGeometry(sza, vza, phi), {})])
    error = (pixel_sigma * rng.standard_normal(pixels)[pixel]
             + scene_sigma * rng.standard_normal(scenes)[scene] * vza / 20 + noise * rng.standard_normal(pixel.size))
    return (sza, vza, phi), design, (design @ WEIGHTS) * (1 + error), pixel, scene


def _meat(design, residuals, clusters):
    scores = np.array([design[clusters == g].T @ residuals[clusters == g] for g in np.unique(clusters)])
    return scores.T @ scores


def test_two_way_sandwich_of_a_linear_model_is_the_closed_form():
    """CR0 sandwiches (no small-sample adjustment): V = B (M_pixel + M_scene - M_pixel&scene) B,
    B = (A^T A)^-1, M the sums of outer products of the clusters' scores A_g^T r_g (Cameron,
    Gelbach and Miller 2011, eq. 2.11), negative eigenvalues set to 0 (section 2.3); formed here
    with numpy from the residuals."""
    angles, design, brdf, pixel, scene = _panel(pixels=15, scenes=6)
    profile = _profile(RTLSR, *angles, brdf[:, None], {})
    coefficients, _ = profile.solve(design)
    found = clustered_covariance(lambda labels: _joint_covariance(profile, {}, design, coefficients, labels,
                                                                  small_sample=False),
                                 TwoWayClusters.of(pixel, scene))
    residuals = brdf - design @ coefficients[:, 0]
    bread = np.linalg.inv(design.T @ design)
    meat = _meat(design, residuals, pixel) + _meat(design, residuals, scene) - _meat(design, residuals,
                                                                                   pixel * 100 + scene)
    values, vectors = np.linalg.eigh(bread @ meat @ bread)
    expected = vectors @ np.diag(np.maximum(values, 0)) @ vectors.T
    np.testing.assert_allclose(found.covariance[0], expected, rtol=1e-8, atol=1e-14 * np.abs(expected).max())
    assert found.n_clusters == 6 and found.scenes  # the scenes, the dimension with fewer clusters


def test_few_scenes_are_named_as_scenes_in_the_reason():
    # Two-way errors limited by 6 scenes read "errors from 6 spatial blocks ... (smaller blocks:
    # fit-classes --block-size)", which cannot help.
    angles, _, brdf, pixel, scene = _panel(pixels=40, scenes=6)
    result = fit_class_samples(RTLSR, *angles, brdf[:, None], clusters=pixel, scenes=scene)
    assert result["n_clusters"] == 6 and result["errors_reliable"] is False
    assert result["errors_reason"].startswith("errors from 6 scenes (two-way over blocks and scenes)")
    assert "more scenes" in result["errors_reason"] and "--block-size" not in result["errors_reason"]


def test_nearest_psd_clears_negative_eigenvalues_only():
    matrix = np.array([[2.0, 0.0], [0.0, -1.0]])
    rotation = np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])
    fixed = nearest_psd(rotation @ matrix @ rotation.T)
    np.testing.assert_allclose(fixed, rotation @ np.diag([2.0, 0.0]) @ rotation.T, atol=1e-15)
    np.testing.assert_allclose(nearest_psd(np.eye(3) * 4.0), np.eye(3) * 4.0)


def test_with_one_scene_two_way_errors_are_the_one_way_pixel_errors():
    angles, design, brdf, pixel, _ = _panel(pixels=30, scenes=5)
    one_way = fit_class_samples(RTLSR, *angles, brdf[:, None], clusters=pixel)
    two_way = fit_class_samples(RTLSR, *angles, brdf[:, None], clusters=pixel, scenes=np.zeros(pixel.size, int))
    np.testing.assert_array_equal(two_way["covariance"], one_way["covariance"])
    np.testing.assert_array_equal(two_way["error_dof"], one_way["error_dof"])


def test_two_way_errors_cover_a_scene_level_error_one_way_errors_miss():
    """Over 60 seeds, pulls (fit - truth) / error of the three weights: an error shared by each
    scene's pixels, growing with the view zenith (it loads on f_vol), makes the one-way
    (pixel-clustered) error of f_vol too small; the two-way errors give pulls of SD near 1 for
    every weight (24 scenes)."""
    one, two = [], []
    for seed in range(60):
        angles, _, brdf, pixel, scene = _panel(pixels=30, scenes=24, seed=seed)
        for pulls, scenes in ((one, None), (two, scene)):
            result = fit_class_samples(RTLSR, *angles, brdf[:, None], clusters=pixel, scenes=scenes)
            values = np.array([result["params"][name][0] for name in ("f_iso", "f_vol", "f_geo")])
            errors = np.array([result["errors"][name][0] for name in ("f_iso", "f_vol", "f_geo")])
            pulls.append((values - WEIGHTS) / errors)
    one_sd, two_sd = np.std(one, axis=0), np.std(two, axis=0)
    assert one_sd[1] > 1.4, one_sd
    assert np.all((two_sd > 0.75) & (two_sd < 1.3)), two_sd


def test_fit_classes_takes_two_way_errors_from_its_sampling(make_lines):
    lines = make_lines(n_lines=3)
    arguments = ([line.reflectance for line in lines], [line.classes for line in lines],
                 [line.angles for line in lines])
    one = fit_classes(*arguments, "ross_thick_li_sparse", sampling=Sampling(levels="pooled", block_size=8))
    two = fit_classes(*arguments, "ross_thick_li_sparse",
                      sampling=Sampling(levels="pooled", block_size=8, errors_cluster="two-way"))
    for a, b in zip(one.fits, two.fits):
        np.testing.assert_array_equal(a.params["f_vol"], b.params["f_vol"])  # the same fit ...
        assert not np.allclose(a.errors["f_vol"], b.errors["f_vol"])  # ... its errors over the lines too:
        assert not b.errors_reliable  # 3 lines are too few clusters to trust them
    with pytest.raises(ParameterError, match="errors cluster"):
        fit_classes(*arguments, "ross_thick_li_sparse", sampling=Sampling(errors_cluster="three-way"))


def test_cli_fits_overlapping_line_files_with_pixel_levels_and_two_way_errors(make_lines, tmp_path):
    """fit-classes over three overlapping line files (each on its own shifted grid): pixel levels
    on the common grid, said so; --errors-cluster two-way gives the same parameters, other errors."""
    from click.testing import CliRunner

    from brdfcorr.cli import main
    from brdfcorr.params import ParameterTable
    from brdfcorr.testing import write_scene

    arguments = []
    for line in make_lines(n_lines=3):
        paths = write_scene(tmp_path / line.name, {"reflectance": line.reflectance, "classes": line.classes,
                                                   **line.angles})
        arguments += [str(paths["image"]), "--classes", str(paths["classes"]), "--angles", str(paths["angles"])]
    tables = {}
    for errors in ("one-way", "two-way"):
        output = tmp_path / f"{errors}.yaml"
        result = CliRunner().invoke(main, ["fit-classes", *arguments, "--model", "ross_thick_li_sparse",
                                           "--levels", "pixel", "--block-size", "8", "--errors-cluster", errors,
                                           "-o", str(output)])
        assert result.exit_code == 0, result.output
        assert "free levels per pixel" in result.output and "seen by two or more scenes" in result.output
        tables[errors] = ParameterTable.load(output)
    for one, two in zip(tables["one-way"].classes, tables["two-way"].classes):
        np.testing.assert_allclose(one.params["f_vol"], two.params["f_vol"], rtol=1e-12)
        assert not np.allclose(one.fit.matrices(), two.fit.matrices())
    refused = CliRunner().invoke(main, ["fit-classes", *arguments, "--errors-cluster", "three-way", "-o",
                                        str(tmp_path / "x.yaml")])
    assert refused.exit_code == 2


def test_library_default_is_the_command_lines():
    from brdfcorr.tasks.options import FIT_CLASSES

    assert Sampling().errors_cluster == FIT_CLASSES.default("errors_cluster") == "one-way"
