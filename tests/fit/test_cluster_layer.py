"""The imagery fit's errors over a cluster layer (issue 40): a raster of ids (a composite's
day-of-year band, a flight-line id) instead of square blocks, in the library and in
``fit-classes --clusters``. Checked against the square-block errors (clusters equal to the blocks)
and against the per-pixel HC2 sandwich computed here, with its Bell-McCaffrey degrees of freedom
(one cluster per pixel)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import ParameterError
from brdfcorr.fit.classes import ClassModels, Sampling, fit_classes
from brdfcorr.fit.sampling import nested_clusters, sample_classes
from brdfcorr.geometry import ScatteringGeometry, relative_azimuth
from brdfcorr.models import get_model
from brdfcorr.params import ParameterTable
from brdfcorr.testing import georeference, render, synthetic_classes, write_scene

TRUTH = ParameterTable(classes=[
    {"id": 1, "name": "roof", "model": "torrance_sparrow", "wavelengths": [560.0, 830.0],
     "params": {"t0": [0.02, 0.05], "t1": [0.15, 0.3], "w": 0.06, "n": 1.6, "k": 0.25}},
    {"id": 2, "name": "field", "model": "ross_thick_li_sparse", "wavelengths": [560.0, 830.0],
     "params": {"f_iso": [0.05, 0.25], "f_vol": [0.02, 0.1], "f_geo": [0.01, 0.03]}},
])


def _line(ny, nx, seed, class_ids=(1, 2)):
    """A push-broom line (sun across track) of the classes of TRUTH, 3 % multiplicative noise and
    an offset shared by 8-pixel squares (albedo)."""
    rng = np.random.default_rng(seed)
    cols = np.linspace(-1, 1, nx)[None, :]
    angles = {"sza": np.broadcast_to(np.linspace(30, 45, ny)[:, None], (ny, nx)).copy(),
              "saa": np.full((ny, nx), 95.0),
              "vza": np.broadcast_to(40 * np.abs(cols), (ny, nx)).copy(),
              "vaa": np.broadcast_to(np.where(cols < 0, 270.0, 90.0), (ny, nx)).copy()}
    classes = synthetic_classes(ny, nx, ids=class_ids, seed=seed)
    shared = np.kron(rng.normal(1.0, 0.03, (-(-ny // 8), -(-nx // 8))), np.ones((8, 8)))[:ny, :nx]
    cube = render(TRUTH, classes, **angles, wavelengths=[560.0, 830.0], brightness=math.pi * shared)
    cube *= 1 + 0.03 * rng.standard_normal(cube.shape)
    coords = {"y": np.arange(ny), "x": np.arange(nx)}
    image = xr.DataArray(cube, dims=("band", "y", "x"),
                         coords={**coords, "band": [1, 2], "wavelength": ("band", [560.0, 830.0])})
    angle_set = xr.Dataset({k: (("y", "x"), v) for k, v in angles.items()}, coords=coords)
    return image, xr.DataArray(classes, dims=("y", "x"), coords=coords), angle_set


def _blocks(shape, size):
    rows, cols = np.indices(shape)
    return (rows // size) * -(-shape[1] // size) + cols // size


def test_clusters_equal_to_the_square_blocks_give_the_block_errors():
    image, classes, angles = _line(64, 96, seed=1)
    models = ClassModels("torrance_sparrow", class_models={2: "ross_thick_li_sparse"})
    sampling = Sampling(block_size=16, max_samples=3000)
    by_blocks = fit_classes(image, classes, angles, models, sampling=sampling)
    # Ids far from the sampler's own block numbers, in another order: only the partition counts.
    layer = 7000 - 3 * _blocks(classes.shape, 16)
    by_layer = fit_classes(image, classes, angles, models, sampling=sampling, clusters=layer)
    for blocks, clustered in zip(by_blocks.fits, by_layer.fits):
        assert clustered.status == blocks.status == "fitted"
        assert clustered.n_samples == blocks.n_samples
        for name in blocks.errors:
            np.testing.assert_allclose(clustered.errors[name], blocks.errors[name], rtol=1e-10, atol=0)
        np.testing.assert_allclose(clustered.covariance, blocks.covariance, rtol=1e-9, atol=1e-300)
        assert clustered.errors_reliable == blocks.errors_reliable
    # The layer is what the errors follow: its 8-pixel squares give other errors than the sampler's 16.
    finer = fit_classes(image, classes, angles, models, sampling=sampling, clusters=_blocks(classes.shape, 8))
    assert not np.allclose(finer.fits[0].errors["w"], by_blocks.fits[0].errors["w"], rtol=1e-3)


def _hc2_errors(design, brdf):
    """Per band (columns of ``brdf``): the least-squares coefficients' HC2 1-sigma (MacKinnon and
    White 1985: Var = (A^T A)^-1 sum_p a_p a_p^T r_p^2 / (1 - h_p) (A^T A)^-1) times the
    t-variance factor nu / (nu - 2) of its Bell-McCaffrey (2002, sec. 5) degrees of freedom
    nu = (tr O)^2 / tr(O^2), O = D (I - H) D, D = diag(a_p^T (A^T A)^-1 c / sqrt(1 - h_p)),
    formed with the N x N hat matrix H."""
    bread = np.linalg.inv(design.T @ design)
    hat = design @ bread @ design.T
    leverage = np.diag(hat)
    annihilator = np.eye(len(design)) - hat
    coefficients = bread @ design.T @ brdf
    residuals = brdf - design @ coefficients
    errors = np.empty((brdf.shape[1], design.shape[1]))
    for band in range(brdf.shape[1]):
        meat = (design * (residuals[:, band] ** 2 / (1 - leverage))[:, None]).T @ design
        variance = np.diag(bread @ meat @ bread)
        for column in range(design.shape[1]):
            weights = (design @ bread[:, column]) / np.sqrt(1 - leverage)
            omega = weights[:, None] * annihilator * weights[None, :]
            dof = np.trace(omega) ** 2 / np.sum(omega * omega)
            errors[band, column] = np.sqrt(variance[column] * dof / (dof - 2))
    return coefficients, errors


def test_one_cluster_per_pixel_gives_the_per_pixel_hc2_sandwich():
    # A kernel-driven class (linear: the fit is one least-squares solve) on every pixel of a small
    # scene, each pixel its own cluster: the errors are the HC2 ones computed here.
    ny, nx = 30, 40
    image, classes, angles = _line(ny, nx, seed=2, class_ids=(2,))
    layer = np.arange(ny * nx).reshape(ny, nx)
    result = fit_classes(image, classes, angles, ClassModels("ross_thick_li_sparse"),
                         sampling=Sampling(max_samples=ny * nx), clusters=layer)
    (fit,) = result.fits
    assert fit.n_samples == ny * nx
    phi = relative_azimuth(angles["saa"].values, angles["vaa"].values).ravel()
    geometry = ScatteringGeometry(angles["sza"].values.ravel(), angles["vza"].values.ravel(), phi)
    design = np.column_stack([np.broadcast_to(np.asarray(term, float), (ny * nx,))
                              for term in get_model("ross_thick_li_sparse").terms(geometry, {})])
    brdf = image.values.reshape(2, -1).T / math.pi
    coefficients, errors = _hc2_errors(design, brdf)
    for column, name in enumerate(("f_iso", "f_vol", "f_geo")):
        np.testing.assert_allclose(fit.params[name], coefficients[column], rtol=1e-9)
        np.testing.assert_allclose(fit.errors[name], errors[:, column], rtol=1e-8)


def test_free_levels_merge_the_clusters_that_share_a_group():
    # Pixel 0 seen in clusters 1 and 2, pixel 1 in 2 and 3, pixel 2 in 5 alone: 1, 2, 3 are one.
    merged = nested_clusters(np.array([1, 2, 2, 3, 5, 5]), np.array([0, 0, 1, 1, 2, 2]))
    assert merged[0] == merged[1] == merged[2] == merged[3] != merged[4] == merged[5]
    # Square blocks of whole patches: nothing to merge (the same partition).
    blocks, patches = np.repeat(np.arange(4), 6), np.repeat(np.arange(12), 2)
    np.testing.assert_array_equal(nested_clusters(blocks, patches), blocks)


def test_pixels_without_an_id_are_not_sampled_and_bad_layers_are_refused():
    image, classes, angles = _line(24, 32, seed=3)
    layer = _blocks(classes.shape, 8).astype(float)
    layer[:, :4] = np.nan
    samples = sample_classes(image, classes, angles, clusters=layer)
    expected = {cid: int(np.sum(classes.values[:, 4:] == cid)) for cid in (1, 2)}
    assert {cid: s.brdf.shape[0] for cid, s in samples.items()} == expected
    assert set(np.unique(samples[1].block)) <= set(np.unique(layer[:, 4:]).astype(int))
    with pytest.raises(ParameterError, match="not integers"):
        sample_classes(image, classes, angles, clusters=layer + 0.5)
    with pytest.raises(ParameterError, match="shape"):
        sample_classes(image, classes, angles, clusters=layer[:, :10])
    with pytest.raises(ParameterError, match="2 cluster layers for 1 scenes"):
        sample_classes(image, classes, angles, clusters=[layer, layer])


def test_fit_classes_clusters_on_the_command_line(tmp_path):
    # --clusters with the 16-pixel blocks as ids gives the report's errors of --block-size 16; a
    # layer per image is required; the source in the table says what the errors are over.
    image, classes, angles = _line(48, 64, seed=4)
    scene = {"reflectance": georeference(image.drop_vars(["x", "y"])),
             "classes": georeference(classes.drop_vars(["x", "y"]).astype(np.uint8)),
             **{k: georeference(angles[k].drop_vars(["x", "y"])) for k in ("sza", "saa", "vza", "vaa")}}
    paths = write_scene(tmp_path / "scene", scene)
    ids = georeference(xr.DataArray(np.stack([_blocks(classes.shape, 16), np.zeros(classes.shape, int)])
                                    .astype(np.int32), dims=("band", "y", "x"), coords={"band": [1, 2]}))
    ids.rio.to_raster(tmp_path / "ids.tif")
    common = ["fit-classes", str(paths["image"]), "--angles", str(paths["angles"]), "--classes", str(paths["classes"]),
              "--class-model", "2=ross_thick_li_sparse", "--scale", "1"]
    reports = {}
    for name, extra in (("blocks", ["--block-size", "16"]), ("layer", ["--clusters", str(tmp_path / "ids.tif")])):
        result = CliRunner().invoke(main, [*common, *extra, "-o", str(tmp_path / f"{name}.yaml"),
                                           "--report", str(tmp_path / f"{name}.json")])
        assert result.exit_code == 0, result.output
        reports[name] = json.loads((tmp_path / f"{name}.json").read_text())["classes"]
    for blocks, layer in zip(reports["blocks"], reports["layer"]):
        for name, values in blocks["errors"].items():
            np.testing.assert_allclose(layer["errors"][name], values, rtol=1e-9)
    sources = {entry.fit.source for entry in ParameterTable.load(tmp_path / "layer.yaml").classes}
    assert all(source.endswith("; errors over the clusters of ids.tif band 1)") for source in sources)
    # Band 2 holds one id: one cluster, errors flagged unreliable (no degrees of freedom).
    result = CliRunner().invoke(main, [*common, "--clusters", str(tmp_path / "ids.tif"), "--cluster-band", "2",
                                       "-o", str(tmp_path / "one.yaml"), "--report", str(tmp_path / "one.json")])
    assert result.exit_code == 0, result.output
    assert all(not entry["errors_reliable"] for entry in json.loads((tmp_path / "one.json").read_text())["classes"])
    twice = CliRunner().invoke(main, [*common, str(paths["image"]), "--angles", str(paths["angles"]), "--classes",
                                      str(paths["classes"]), "--clusters", str(tmp_path / "ids.tif"),
                                      "-o", str(tmp_path / "bad.yaml")])
    assert twice.exit_code == 2 and "2 image(s) and 1 --clusters" in twice.output
    assert not (tmp_path / "bad.yaml").exists()


def test_free_levels_per_pixel_get_clusters_that_hold_every_view_of_a_pixel():
    # Two dates on one grid, each pixel's level free: a pixel's two views lie in one cluster. The
    # same column strips in both dates stay apart (one cluster per strip holding pixels of the
    # class); strips by column in one date and by row in the other chain every pixel together.
    image, classes, angles = _line(24, 32, seed=5)
    rows, cols = np.indices(classes.shape)
    by_column, by_row = cols // 8, 100 + rows // 8
    same = sample_classes([image, image], [classes, classes], [angles, angles], clusters=[by_column, by_column], sampling=Sampling(levels="pixel"))
    for class_id, samples in same.items():
        strips = np.unique(by_column[classes.values == class_id])
        assert np.unique(samples.block).size == strips.size
        for group in np.unique(samples.group):
            assert np.unique(samples.block[samples.group == group]).size == 1
    crossed = sample_classes([image, image], [classes, classes], [angles, angles], clusters=[by_column, by_row], sampling=Sampling(levels="pixel"))
    assert all(np.unique(samples.block).size == 1 for samples in crossed.values())


def test_a_dated_cluster_layer_takes_the_cubes_dates_by_label():
    # A (time, y, x) layer stored newest first was paired with the cube's dates by position, while
    # its class maps and angles are paired by label: f_vol's error came out 1.6 times too large.
    import pandas as pd

    dates = pd.Index(pd.date_range("2024-04-01", periods=3, freq="10D"), name="time")
    lines = [_line(32, 48, seed) for seed in range(3)]
    cube = xr.concat([line[0] for line in lines], dim=dates)
    angles = xr.concat([line[2] for line in lines], dim=dates)
    ids = np.stack([date * 100 + _blocks((32, 48), 8 * (date + 1)) for date in range(3)])
    layer = xr.DataArray(ids, dims=("time", "y", "x"), coords={"time": dates})

    def errors(clusters):
        fit = fit_classes(cube, lines[0][1], angles, ClassModels("ross_thick_li_sparse", class_ids=[2]),
                          sampling=Sampling(levels="pooled"), clusters=clusters).fits[0]
        return np.concatenate([fit.errors[name] for name in ("f_iso", "f_vol", "f_geo")])

    in_order = errors(layer)
    np.testing.assert_array_equal(errors(layer.isel(time=[2, 1, 0])), in_order)
    by_position = errors([layer.isel(time=index, drop=True) for index in (2, 1, 0)])  # a list: in order
    assert not np.allclose(by_position, in_order)
