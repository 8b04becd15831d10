"""`correct --output-type input`: an integer input's type, scale, offset and nodata for the output
(issue 16). The float output of the same run is the reference: ``stored = round(float / scale)``
exactly, and values that do not fit the type are nodata and flagged, never wrapped or clipped."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.correction import QA
from brdfcorr.testing import synthetic_scene


def _correct(paths, image, output, *extra):
    args = ["correct", image, "--angles", paths["angles"], "--classes", paths["classes"], "--params",
            paths["params"], "-o", output, "--ref-sza", "35", "--no-progress", *extra]
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    return result


@pytest.fixture(scope="module")
def paths(tmp_path_factory, write_example_scene):
    return write_example_scene(tmp_path_factory.mktemp("output_type"), synthetic_scene(ny=40, nx=48))


def test_int16_output_keeps_the_input_storage(paths, tmp_path, store):
    image = store(paths["image"], tmp_path / "int16.tif", "int16", 1e-4, 0.0, -9999)
    _correct(paths, image, tmp_path / "float.tif")
    _correct(paths, image, tmp_path / "int.tif", "--output-type", "input", "--qa", tmp_path / "qa.tif")
    with rasterio.open(tmp_path / "float.tif") as reference, rasterio.open(tmp_path / "int.tif") as stored:
        assert stored.dtypes == ("int16",) * stored.count and reference.dtypes[0] == "float32"
        assert stored.nodata == -9999 and stored.scales == (1e-4,) * stored.count
        assert stored.offsets == (0.0,) * stored.count
        assert stored.descriptions == reference.descriptions and stored.tags()["brdf_reference"]
        assert stored.tags(ns="IMAGE_STRUCTURE").get("PREDICTOR") == "2"  # the integer predictor
        values, expected = stored.read(), reference.read().astype(np.float64)
    valid = np.isfinite(expected)
    np.testing.assert_array_equal(values[valid], np.round(expected[valid] / 1e-4))
    assert np.all(values[~valid] == -9999) and (~valid).any()
    with rasterio.open(tmp_path / "qa.tif") as qa:
        assert not (qa.read(1) & QA.NODATA)[valid.all(axis=0)].any()  # nothing out of range here


def test_values_beyond_the_type_are_nodata_and_flagged(paths, tmp_path, store):
    # uint8 at 0.004 per count (255 = nodata): a bright scene whose corrected values exceed 254 counts
    # where the factor is above 1 in some band.
    with rasterio.open(paths["image"]) as dataset:
        profile, descriptions = dataset.profile, dataset.descriptions
    bright = tmp_path / "bright.tif"
    rng = np.random.default_rng(3)
    values = rng.uniform(0.90, 0.99, size=(profile["count"], profile["height"], profile["width"]))
    with rasterio.open(bright, "w", **profile) as dataset:
        dataset.write(values.astype(np.float32))
        dataset.descriptions = descriptions
    image = store(bright, tmp_path / "uint8.tif", "uint8", 0.004, 0.0, 255)
    _correct(paths, image, tmp_path / "float.tif")
    _correct(paths, image, tmp_path / "int.tif", "--output-type", "input", "--qa", tmp_path / "qa.tif")
    with rasterio.open(tmp_path / "float.tif") as reference, rasterio.open(tmp_path / "int.tif") as stored, \
            rasterio.open(tmp_path / "qa.tif") as qa:
        counts = np.round(reference.read().astype(np.float64) / 0.004)
        values, flags = stored.read(), qa.read(1)
    beyond = np.isfinite(counts) & (counts >= 255)
    assert beyond.any() and (~beyond & np.isfinite(counts)).any()  # both cases occur
    assert np.all(values[beyond] == 255)
    fits = np.isfinite(counts) & ~beyond
    np.testing.assert_array_equal(values[fits], counts[fits])
    np.testing.assert_array_equal((flags & QA.NODATA) > 0, ~np.isfinite(counts).all(axis=0) | beyond.any(axis=0))


def test_float_input_stays_float(paths, tmp_path):
    _correct(paths, paths["image"], tmp_path / "a.tif", "--output-type", "input")
    _correct(paths, paths["image"], tmp_path / "b.tif")
    with rasterio.open(tmp_path / "a.tif") as a, rasterio.open(tmp_path / "b.tif") as b:
        assert a.dtypes == b.dtypes and np.array_equal(a.read(), b.read(), equal_nan=True)
