"""The per-pixel factor evaluated on a fine sample grid (brdfcorr.correction.subgrid) against the
straightforward per-pixel evaluation (:func:`brdfcorr.correction.normalize`, the reference).

Issue 41's bound: within 0.01 % of the per-pixel factor everywhere, over a whole real tile's angle
grids (T23LLF, tests/data, at 60 m: 1830 x 1830 pixels, 83 between nodes, so the sample grid's
spacing is as many metres as at 10 m and 20 m and the error as large).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from brdfcorr.correction import QA, normalize, normalize_at_nodes
from brdfcorr.correction.subgrid import axis_samples, normalize_on_subgrid, suits_subgrid
from brdfcorr.errors import ParameterError
from brdfcorr.io.sensors.sentinel2 import read_sentinel2_angles
from brdfcorr.models.coefficients import load_coefficients
from brdfcorr.params import ClassEntry, ParameterTable, ReferenceGeometry

MTD = Path(__file__).parents[1] / "data" / "s2_MTD_TL_sensor_harmonization" / "MTD_TL.xml"
BANDS = ("B02", "B03", "B04", "B05", "B06", "B07", "B08", "B11", "B12")
ANGLES = ("sza", "saa", "vza", "vaa")


def _roy2017(bands) -> ParameterTable:
    entry = load_coefficients("roy2017").table_entry(1, sensor="sentinel2", bands=list(bands))
    return ParameterTable(classes=[ClassEntry(**entry)])


@pytest.mark.parametrize(("band", "reference_sza"), [(None, "observed"), ("B02", 40.0)])
def test_whole_real_tile_within_a_hundredth_of_a_percent(band, reference_sza):
    """Every pixel and band of the whole tile: |sampled / per-pixel - 1| < 1e-4 (issue 41), and
    no pixel valid in one and not in the other. View grids averaged over the bands with the
    observed sun (sen2nbar's reference), and B02's own with a fixed one."""
    angles = read_sentinel2_angles(MTD, resolution=60, band=band, chunks=610)
    layers = {name: angles[name] for name in ANGLES}
    bands = BANDS if band is None else (band,)
    ones = xr.ones_like(angles["sza"], dtype=np.float32).expand_dims(band=np.arange(1, len(bands) + 1))
    table, reference = _roy2017(bands), ReferenceGeometry(sza=reference_sza, vza=0.0, raa=0.0)
    assert suits_subgrid(ones, layers, table)
    exact = normalize(ones, None, layers, table, reference, limits=None).reflectance.values
    sampled = normalize_on_subgrid(ones, layers, table, reference, limits=None).reflectance.values
    assert np.array_equal(np.isfinite(exact), np.isfinite(sampled))
    error = np.abs(sampled / exact - 1)
    assert np.nanmax(error) < 1e-4
    assert np.abs(exact - 1).max() > 0.02  # 3.5 % somewhere: a real correction


def test_axis_samples_keep_the_nodes_kinks_and_the_step():
    """First and last pixel, both pixels around every node (where the bilinear angles kink), and
    no gap above a sixteenth of a cell plus one pixel (rounding) with 16 subdivisions."""
    positions = (np.arange(1000) + 0.5) / 83.0 - 0.5  # 83 pixels per cell, node k at position k
    samples = axis_samples(positions, 13, subdivisions=16)
    assert samples[0] == 0 and samples[-1] == 999
    for node in range(13):
        after = np.searchsorted(positions, node)
        if 0 < after < 1000:
            assert {after - 1, after} <= set(samples.tolist())
    assert np.diff(samples).max() <= np.ceil(83 / 16) + 1


TABLE = ParameterTable(classes=[{"id": 1, "name": "global", "model": "ross_thick_li_sparse",
                                 "params": {"f_iso": [0.05, 0.3], "f_vol": [0.02, 0.15], "f_geo": [0.005, 0.04]},
                                 "wavelengths": [450.0, 900.0]}])


@pytest.fixture
def scene(node_scene):
    """Sun and view angles on a 5 x 6 grid of 100 m nodes, interpolated to 20 m (25 x 30 pixels,
    chunks of 16, one chunk 9 pixels wide); the sun at the lower right beyond 90 deg (invalid
    geometry there); NaN and +inf reflectance at two pixels."""
    rows, cols = np.meshgrid(np.arange(5.0), np.arange(6.0), indexing="ij")
    coarse = {"sza": 30.0 + 10.0 * rows + 5.0 * cols, "saa": 140.0 + 3.0 * cols, "vza": 1.0 + 1.8 * cols + 0.3 * rows,
              "vaa": 100.0 + 40.0 * rows}
    data = np.random.default_rng(3).uniform(0.05, 0.5, (3, 25, 30)).astype(np.float32)
    data[1, 3, 4], data[2, 10, 11] = np.nan, np.inf
    return node_scene(coarse, data)


@pytest.mark.parametrize("reference", [ReferenceGeometry(sza=40.0, vza=0.0, raa=0.0),
                                       ReferenceGeometry(sza="observed", vza=10.0, raa=30.0)])
def test_flags_and_values_as_the_per_pixel_correction(scene, reference):
    """The values within 1e-4 of normalize's and the QA flags equal (nodata, invalid geometry,
    limited at limits (0.9, 1.1)) except where the per-pixel factor lies within 1e-4 of a limit.
    Two subdivisions of the 5-pixel cells: samples 2-3 pixels apart, so most pixels interpolated."""
    image, angles = scene
    limits = (0.9, 1.1)
    ours, our_qa = normalize_on_subgrid(image, angles, TABLE, reference, limits=limits, subdivisions=2)
    theirs, their_qa = normalize(image, None, angles, TABLE, reference, limits=limits)
    ours, theirs = ours.values, theirs.values
    assert np.array_equal(np.isnan(ours), np.isnan(theirs))
    np.testing.assert_allclose(ours[np.isfinite(theirs)], theirs[np.isfinite(theirs)], rtol=1e-4)
    factor = normalize(image, None, angles, TABLE, reference, limits=None).reflectance.values / image.values
    near = (np.abs(factor / limits[0] - 1) < 1e-4) | (np.abs(factor / limits[1] - 1) < 1e-4)
    settled = ~near.any(axis=0)
    np.testing.assert_array_equal(our_qa.values[settled], their_qa.values[settled])
    for flag in (QA.NODATA, QA.INVALID_GEOMETRY, QA.LIMITED):  # each case occurs in the scene
        assert (their_qa.values & flag).any()


def test_not_suited_without_a_coarse_grid_or_with_two_classes(scene):
    image, angles = scene
    assert suits_subgrid(image, angles, TABLE)
    per_pixel = {**angles, "vza": angles["vza"].copy(data=angles["vza"].data)}
    per_pixel["vza"].encoding = {}
    assert not suits_subgrid(image, per_pixel, TABLE)
    two = ParameterTable(classes=[TABLE.classes[0], TABLE.classes[0].model_copy(update={"id": 2})])
    assert not suits_subgrid(image, angles, two)
    assert not suits_subgrid(image.astype(np.int16), angles, TABLE)


def test_a_table_that_does_not_fit_the_bands_is_refused_before_any_block(scene):
    """A table of 600-700 nm for bands at 490 and 842 nm: the same ParameterError as normalize's,
    raised by the call itself (the result is lazy: no block computed), as normalize raises it."""
    image, angles = scene
    narrow = ParameterTable(classes=[{**TABLE.classes[0].model_dump(exclude_none=True), "wavelengths": [600.0, 700.0]}])
    reference = ReferenceGeometry(sza=40.0, vza=0.0, raa=0.0)
    with pytest.raises(ParameterError) as theirs:
        normalize(image, None, angles, narrow, reference)
    with pytest.raises(ParameterError) as ours:
        normalize_on_subgrid(image, angles, narrow, reference)
    assert str(ours.value) == str(theirs.value)


def test_a_product_beyond_float32_is_nodata_in_every_method(scene):
    """3.3e38 times a factor above 1 is beyond float32: per pixel it was +inf with no flag, counted
    corrected; at the nodes +inf flagged nodata. Now NaN and nodata in all three."""
    image, angles = scene
    data = image.values.copy()
    data[:, 12, 20] = 3.3e38
    image = image.copy(data=data).chunk({"y": 16, "x": 16})
    reference = ReferenceGeometry(sza=20.0, vza=0.0, raa=0.0)  # a factor above 1 at this pixel
    assert (normalize(xr.full_like(image, 0.1), None, angles, TABLE, reference).reflectance.values[:, 12, 20] > 0.1).all()
    for method in (lambda: normalize(image, None, angles, TABLE, reference),
                   lambda: normalize_on_subgrid(image, angles, TABLE, reference),
                   lambda: normalize_at_nodes(image, angles, TABLE, reference)):
        corrected, qa = method()
        assert np.isnan(corrected.values[:, 12, 20]).all() and qa.values[12, 20] & QA.NODATA
        assert not np.isinf(corrected.values).any()


def test_a_mean_reference_is_the_mean_of_the_pixels_in_every_method(scene):
    """"mean" was the mean of each evaluation's own points (a block's samples, the nodes): chunk-
    dependent and up to 6 % off. It is the pixels' mean sun zenith, as for normalize."""
    image, angles = scene
    valid = angles["sza"].values[(angles["sza"].values >= 0) & (angles["sza"].values < 90)]
    fixed = ReferenceGeometry(sza=float(valid.mean()), vza=0.0, raa=0.0)
    mean = ReferenceGeometry(sza="mean", vza=0.0, raa=0.0)
    for method in (normalize_on_subgrid, normalize_at_nodes):
        np.testing.assert_allclose(method(image, angles, TABLE, mean).reflectance.values,
                                   method(image, angles, TABLE, fixed).reflectance.values, rtol=1e-12)
    np.testing.assert_allclose(normalize(image, None, angles, TABLE, mean).reflectance.values,
                               normalize(image, None, angles, TABLE, fixed).reflectance.values, rtol=1e-6)


def test_bands_in_chunks_of_one_take_a_table_given_per_band_by_position(scene):
    """A table of three per-band values without wavelengths met each one-band chunk alone:
    ParameterError "f_iso has 3 per-band values but the image has 1 bands"."""
    image, angles = scene
    entry = TABLE.classes[0].model_dump(exclude_none=True)
    by_position = ParameterTable(classes=[{**{k: v for k, v in entry.items() if k != "wavelengths"},
                                           "params": {"f_iso": [0.05, 0.2, 0.3], "f_vol": [0.02, 0.1, 0.15],
                                                      "f_geo": [0.005, 0.02, 0.04]}}])
    reference = ReferenceGeometry(sza=40.0, vza=0.0, raa=0.0)
    whole = normalize_on_subgrid(image, angles, by_position, reference).reflectance.values
    split = normalize_on_subgrid(image.chunk({"band": 1}), angles, by_position, reference).reflectance.values
    np.testing.assert_array_equal(split, whole)
