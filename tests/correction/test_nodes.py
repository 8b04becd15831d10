"""The correction factor at the nodes of a coarse angle grid (brdfcorr.correction.nodes).

The scene: smooth sun and view angles on a 5 x 6 grid of 100 m nodes, interpolated to a 20 m
image by the sensor readers' :func:`brdfcorr.io.sensors.grids.to_grid`, so that every fifth pixel
(rows and columns 2, 7, 12, ...) is centred on a node.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from brdfcorr.correction import QA, normalize, normalize_at_nodes
from brdfcorr.errors import InputError
from brdfcorr.params import ParameterTable, ReferenceGeometry

TABLE = ParameterTable(classes=[{"id": 1, "name": "global", "model": "ross_thick_li_sparse",
                                 "params": {"f_iso": [0.05, 0.3], "f_vol": [0.02, 0.15], "f_geo": [0.005, 0.04]},
                                 "wavelengths": [450.0, 900.0]}])
REFERENCE = ReferenceGeometry(sza=40.0, vza=0.0, raa=0.0)


@pytest.fixture
def scene(node_scene):
    rows, cols = np.meshgrid(np.arange(5.0), np.arange(6.0), indexing="ij")
    coarse = {"sza": 30.0 + 2.0 * rows + cols, "saa": 140.0 + 3.0 * cols, "vza": 1.0 + 1.8 * cols + 0.3 * rows,
              "vaa": 100.0 + 20.0 * rows}
    return node_scene(coarse, np.random.default_rng(3).uniform(0.05, 0.5, (3, 25, 30)).astype(np.float32))


def test_pixels_on_the_nodes_get_the_per_pixel_factor(scene):
    """Where a pixel is centred on a node, the interpolated factor is that node's: the result equals
    the per-pixel correction there (float32 rounding). Between the nodes the factor is a bilinear,
    so convex, combination of its four nodes' factors: within their range."""
    image, angles = scene
    nodes, qa = normalize_at_nodes(image, angles, TABLE, REFERENCE)
    pixels, _ = normalize(image, xr.ones_like(angles["sza"], dtype=np.uint8), angles, TABLE, REFERENCE)
    reflectance, nodes, pixels = image.values.astype(np.float64), nodes.values, pixels.values
    on_nodes = (slice(None), slice(2, None, 5), slice(2, None, 5))
    np.testing.assert_allclose(nodes[on_nodes], pixels[on_nodes], rtol=2e-6)
    factor, node_factor = nodes / reflectance, (pixels / reflectance)[on_nodes]
    assert np.abs(factor - 1).min() > 1e-3  # a correction took place everywhere
    for row in range(2, 22):
        for col in range(2, 27):
            i, j = (row - 2) // 5, (col - 2) // 5
            corners = node_factor[:, i:i + 2, j:j + 2].reshape(3, -1)
            assert (corners.min(axis=1) - 1e-6 <= factor[:, row, col]).all()
            assert (factor[:, row, col] <= corners.max(axis=1) + 1e-6).all()
    assert (qa.values == 0).all()


def test_view_azimuths_from_the_sensor_are_flipped_as_per_pixel(scene):
    """flip_view_azimuth (view azimuths from the sensor): the pixels on the nodes get the
    per-pixel factor with the same flip, which differs from the unflipped one."""
    image, angles = scene
    nodes, _ = normalize_at_nodes(image, angles, TABLE, REFERENCE, flip_view_azimuth=True)
    classes = xr.ones_like(angles["sza"], dtype=np.uint8)
    flipped, _ = normalize(image, classes, angles, TABLE, REFERENCE, flip_view_azimuth=True)
    unflipped, _ = normalize(image, classes, angles, TABLE, REFERENCE)
    on_nodes = (slice(None), slice(2, None, 5), slice(2, None, 5))
    np.testing.assert_allclose(nodes.values[on_nodes], flipped.values[on_nodes], rtol=2e-6)
    assert np.abs(flipped.values[on_nodes] / unflipped.values[on_nodes] - 1).max() > 1e-2


def test_limits_clip_the_factor_and_flag_the_pixels(scene):
    """Limits (1, 1): the factor is 1, every corrected value the input, and every pixel whose
    nodes' factors were clipped (all of them: no factor is exactly 1 here) is flagged limited."""
    image, angles = scene
    corrected, qa = normalize_at_nodes(image, angles, TABLE, REFERENCE, limits=(1.0, 1.0))
    np.testing.assert_array_equal(corrected.values, image.values)
    assert (qa.values == QA.LIMITED).all()


def test_nodata_in_a_band_is_flagged_and_kept(scene):
    image, angles = scene
    image = image.copy(data=image.data.copy())
    image[1, 3, 4] = np.nan
    corrected, qa = normalize_at_nodes(image, angles, TABLE, REFERENCE)
    assert np.isnan(corrected.values[1, 3, 4]) and np.isfinite(corrected.values[[0, 2], 3, 4]).all()
    assert qa.values[3, 4] == QA.NODATA and (np.delete(qa.values.ravel(), 3 * 30 + 4) == 0).all()


def test_per_pixel_angle_rasters_are_refused(scene):
    image, angles = scene
    per_pixel = {**angles, "vza": angles["vza"].copy(data=angles["vza"].data)}
    per_pixel["vza"].encoding = {}
    with pytest.raises(InputError, match="vza are per-pixel rasters"):
        normalize_at_nodes(image, per_pixel, TABLE, REFERENCE)


@pytest.mark.parametrize("band_chunks", [-1, 1])
def test_inf_reflectance_is_nodata_and_the_flags_are_the_per_pixel_ones(scene, band_chunks):
    """+-inf input was written as +-inf (per pixel: NaN), and a pixel NaN in one band lost its
    `limited` flag where all bands shared one chunk (it kept it with one band per chunk)."""
    image, angles = scene
    data = image.values.copy()
    data[0, 6, 6], data[2, 7, 7], data[1, 3, 4] = np.inf, -np.inf, np.nan
    image = image.copy(data=data).chunk({"band": band_chunks})
    corrected, qa = normalize_at_nodes(image, angles, TABLE, REFERENCE, limits=(1.0, 1.0))
    _, pixel_qa = normalize(image, xr.ones_like(angles["sza"], dtype=np.uint8), angles, TABLE, REFERENCE,
                            limits=(1.0, 1.0))
    assert np.isnan(corrected.values[0, 6, 6]) and np.isnan(corrected.values[2, 7, 7])
    assert np.isinf(corrected.values).sum() == 0
    np.testing.assert_array_equal(qa.values, pixel_qa.values)
    assert qa.values[3, 4] == QA.NODATA | QA.LIMITED


def test_integer_reflectance_stays_integer(scene):
    # Counts (uint16) as the Python API may be given them: the nodata assignment of float outputs
    # raised "cannot convert float NaN to integer" (the command line scales to floats first).
    image, angles = scene
    counts = image.copy(data=(image.data * 10000).astype(np.uint16))
    corrected, qa = normalize_at_nodes(counts, angles, TABLE, REFERENCE)
    floats, _ = normalize_at_nodes(counts.astype(np.float64), angles, TABLE, REFERENCE)
    assert corrected.dtype == np.uint16
    np.testing.assert_array_equal(corrected.values, floats.values.astype(np.uint16))
