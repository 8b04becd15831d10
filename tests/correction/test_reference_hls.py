"""The reference sun zenith ``"hls"``: HLS v1.4's NBAR sun zenith for the scene centre's latitude,
a 6th-order polynomial in latitude (NASA HLS v1.4 User Guide, p. 13; Claverie et al. 2018)."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
import rasterio.control
import rioxarray
from click.testing import CliRunner
from pyproj import Transformer

from brdfcorr.cli import main
from brdfcorr.correction import normalize
from brdfcorr.correction.reference import hls_sza
from brdfcorr.errors import InputError
from brdfcorr.testing import example_table, synthetic_scene

# The published coefficients, written out here (not read from brdfcorr): k0 ... k6.
K = (31.0076, -0.1272, 0.01187, 2.40e-05, -9.48e-07, -1.95e-09, 6.15e-11)


def published(latitude: float) -> float:
    return sum(k * latitude**power for power, k in enumerate(K))


@pytest.mark.parametrize("latitude", [0.0, 23.4, 45.0, -33.9, 60.0])
def test_the_polynomial_is_the_published_one(latitude):
    assert hls_sza(latitude) == pytest.approx(published(latitude), rel=1e-12)
    assert hls_sza(0.0) == 31.0076  # the constant term: the equator


def test_a_latitude_outside_minus_90_90_is_refused():
    with pytest.raises(ValueError, match="outside"):
        hls_sza(91.0)


def _centre_latitude(image) -> float:
    """The image centre's latitude, from its transform and CRS, independently of brdfcorr."""
    x, y = image.rio.transform() * (image.sizes["x"] / 2, image.sizes["y"] / 2)
    return Transformer.from_crs(image.rio.crs, "EPSG:4326", always_xy=True).transform(x, y)[1]


def test_normalize_takes_hls_as_that_fixed_sun_zenith():
    scene = synthetic_scene(ny=12, nx=16)
    angles = {name: scene[name] for name in ("sza", "saa", "vza", "vaa")}
    expected = published(_centre_latitude(scene["reflectance"]))
    hls, _ = normalize(scene["reflectance"], scene["classes"], angles, example_table(), {"sza": "hls", "vza": 0.0})
    fixed, _ = normalize(scene["reflectance"], scene["classes"], angles, example_table(), {"sza": expected, "vza": 0.0})
    np.testing.assert_allclose(hls.values, fixed.values, rtol=1e-6)
    assert hls.attrs["brdf_reference"].startswith(f"sza={expected:g}")


def test_correct_with_ref_sza_hls_tags_the_value_and_its_source(scene, correct_args):
    # tests/conftest.py's 32 x 32 example scene on disk (the same georeference as synthetic_scene).
    output = scene["output"]
    result = CliRunner().invoke(main, [str(a) for a in correct_args(scene, "--ref-sza", "hls")])
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset:
        tags = dataset.tags()
        x, y = dataset.transform * (dataset.width / 2, dataset.height / 2)
        latitude = Transformer.from_crs(dataset.crs, "EPSG:4326", always_xy=True).transform(x, y)[1]
    assert tags["brdf_reference_sza_source"] == "hls"
    assert float(tags["brdf_reference"].split()[0].removeprefix("sza=")) == pytest.approx(published(latitude),
                                                                                          abs=1e-4)


def _with_gcps(scene, tmp_path):
    """The scene's image written with four ground control points (the corners' true places) and no
    geotransform: rioxarray reads it with the GCPs' CRS and an identity transform."""
    reflectance = scene["reflectance"]
    transform, (rows, columns) = reflectance.rio.transform(), reflectance.shape[1:]
    gcps = [rasterio.control.GroundControlPoint(row, col, *(transform * (col, row)))
            for row, col in ((0, 0), (0, columns), (rows, 0), (rows, columns))]
    path = tmp_path / "gcps.tif"
    with rasterio.open(path, "w", driver="GTiff", width=columns, height=rows, count=reflectance.shape[0],
                       dtype="float32", gcps=gcps, crs=reflectance.rio.crs) as dataset:
        dataset.write(reflectance.values.astype("float32"))
    return path


def test_an_image_georeferenced_by_ground_control_points_has_no_latitude_for_hls(tmp_path):
    """Its identity transform would put the centre at the CRS's origin: the equator in UTM (hls
    31.0 deg for a scene at 48.7 deg N, whose hls sun zenith is 50.7), corrected without a word."""
    scene = synthetic_scene(ny=12, nx=16)
    image = rioxarray.open_rasterio(_with_gcps(scene, tmp_path), mask_and_scale=True)
    assert image.rio.crs == scene["reflectance"].rio.crs and image.rio.transform().is_identity
    angles = {name: scene[name].values for name in ("sza", "saa", "vza", "vaa")}  # on its grid by shape
    with pytest.raises(InputError, match=r"^the image \(.*gcps\.tif\) is georeferenced by ground control points, "
                                         r"not a geotransform, and the reference sun zenith 'hls'"):
        normalize(image, scene["classes"].values, angles, example_table(),
                  {"sza": "hls", "vza": 0.0})
