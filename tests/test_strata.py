"""Tests of brdfcorr.strata: NDVI against its closed form, NDVI bins and masks, code remapping, and
class maps aligned from other grids and CRSs (expected classes located independently with pyproj)."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import xarray as xr
from affine import Affine
from pyproj import Transformer

from brdfcorr.errors import InputError
from brdfcorr.strata import (
    DEFAULT_EDGES,
    WORLDCOVER_CODES,
    align_class_map,
    ndvi,
    ndvi_strata,
    remap_classes,
)
from brdfcorr.testing import CRS, ORIGIN, PIXEL, georeference

WAVELENGTHS = (480.0, 560.0, 660.0, 850.0)  # blue, green, red (620-690 nm), NIR (780-900 nm)


def _image(red, nir, visible=None, wavelengths=WAVELENGTHS) -> xr.DataArray:
    """A (band, y, x) reflectance image whose red and NIR bands hold ``red`` and ``nir``."""
    red, nir = np.atleast_2d(np.asarray(red, float)), np.atleast_2d(np.asarray(nir, float))
    visible = red if visible is None else np.atleast_2d(np.asarray(visible, float))
    cube = np.stack([visible, visible, red, nir])
    return georeference(xr.DataArray(
        cube, dims=("band", "y", "x"), name="reflectance",
        coords={"band": [1, 2, 3, 4], "wavelength": ("band", list(wavelengths), {"units": "nm"})},
    ))


def _lazy(array: xr.DataArray, chunk: int) -> xr.DataArray:
    """Chunk the data only (coords stay numpy, as rioxarray opens them)."""
    chunks = tuple(-1 if dim == "band" else chunk for dim in array.dims)
    return array.copy(data=da.from_array(array.values, chunks=chunks))


def _grid(values, pixel: float, origin=ORIGIN, crs=CRS, nodata=None) -> xr.DataArray:
    """A (y, x) class map with square pixels of ``pixel`` CRS units from the top-left ``origin``."""
    values = np.asarray(values)
    ny, nx = values.shape
    array = xr.DataArray(values, dims=("y", "x"), name="classes", coords={
        "x": origin[0] + pixel * (np.arange(nx) + 0.5), "y": origin[1] - pixel * (np.arange(ny) + 0.5)})
    array = array.rio.write_crs(crs).rio.write_transform(Affine(pixel, 0, origin[0], 0, -pixel, origin[1]))
    return array.rio.write_nodata(nodata) if nodata is not None else array


# -- NDVI ---------------------------------------------------------------------------------------

def test_ndvi_closed_form():
    # NDVI = (NIR - red) / (NIR + red): 0.8, 0, -0.5, undefined (0/0), NaN in, 1.
    red = [0.05, 0.2, 0.3, 0.0, np.nan, 0.0]
    nir = [0.45, 0.2, 0.1, 0.0, 0.3, 0.4]
    expected = [0.8, 0.0, -0.5, np.nan, np.nan, 1.0]
    image = _image(red, nir)
    result = ndvi(image)
    np.testing.assert_allclose(result.values[0], expected, rtol=1e-12)
    assert result.dims == ("y", "x") and result.attrs["units"] == "1"
    assert result.rio.crs == image.rio.crs and result.rio.transform() == image.rio.transform()
    lazy = ndvi(_lazy(image, 2))
    assert isinstance(lazy.data, da.Array)
    np.testing.assert_array_equal(lazy.values, result.values)


def test_ndvi_averages_the_bands_in_each_range():
    # Two NIR bands (800, 860 nm: 0.4 and 0.6, mean 0.5), red 0.1: NDVI = 0.4 / 0.6 = 2/3.
    cube = np.array([0.05, 0.1, 0.4, 0.6]).reshape(4, 1, 1)
    image = georeference(xr.DataArray(cube, dims=("band", "y", "x"),
                                      coords={"wavelength": ("band", [500.0, 665.0, 800.0, 860.0])}))
    np.testing.assert_allclose(ndvi(image).values, [[2 / 3]], rtol=1e-12)


def test_ndvi_errors_name_the_problem():
    image = _image([0.1], [0.4])
    with pytest.raises(InputError, match=r"no band centres .*give them \(wavelengths=\)"):
        ndvi(image.drop_vars("wavelength"))
    from brdfcorr._entry import entered

    with entered("cli"), pytest.raises(InputError, match=r"no band centres .*give them \(--wavelengths\)"):
        ndvi(image.drop_vars("wavelength"))
    with pytest.raises(InputError, match=r"red range 700-710 nm \(its bands span 480-850 nm\)"):
        ndvi(image, red=(700, 710))


# -- NDVI strata --------------------------------------------------------------------------------

def _with_ndvi(values) -> xr.DataArray:
    """An image with exactly the given (dyadic) NDVI values: red + NIR = 1, so NDVI = NIR - red."""
    values = np.asarray(values, float)
    return _image((1 - values) / 2, (1 + values) / 2)


def test_fixed_edges_are_left_closed():
    # Dyadic NDVI values are exact in binary, so a pixel exactly at an edge falls in the bin above.
    values = [-0.5, 0.0, 0.25, 0.375, 0.5, 0.75, 1.0]
    strata = ndvi_strata(_with_ndvi(values), edges=(0.25, 0.5, 0.75))
    np.testing.assert_array_equal(strata.classes.values[0], [1, 1, 2, 2, 3, 4, 4])
    assert strata.edges == (0.25, 0.5, 0.75)
    assert strata.names == {1: "ndvi_-inf_0.25", 2: "ndvi_0.25_0.50", 3: "ndvi_0.50_0.75", 4: "ndvi_0.75_inf"}


def test_default_edges_and_attrs():
    # Red 0.1, NIR chosen for NDVI 0.05, 0.2, 0.4, 0.6, 0.8 (NIR = red (1 + v) / (1 - v)).
    values = np.array([0.05, 0.2, 0.4, 0.6, 0.8])
    image = _image(np.full(5, 0.1), 0.1 * (1 + values) / (1 - values))
    strata = ndvi_strata(image)
    classes = strata.classes
    np.testing.assert_array_equal(classes.values[0], [1, 2, 3, 4, 5])
    assert strata.edges == DEFAULT_EDGES == (0.1, 0.3, 0.5, 0.7)
    assert strata.names[2] == "ndvi_0.10_0.30" and strata.names[5] == "ndvi_0.70_inf"
    assert classes.dtype == np.uint8 and classes.rio.nodata == 0
    assert classes.rio.crs == image.rio.crs and classes.rio.transform() == image.rio.transform()
    assert classes.attrs["ndvi_edges"] == "0.1,0.3,0.5,0.7" and classes.attrs["strata"] == "ndvi_edges"
    assert classes.attrs["class_names"].startswith("1=ndvi_-inf_0.10;2=ndvi_0.10_0.30")


def test_percentile_bins_hold_near_equal_counts():
    rng = np.random.default_rng(3)
    values = rng.uniform(-0.2, 0.9, size=(40, 50))
    values[:20, :16] = np.nan  # chunks with unequal numbers of valid pixels
    # Red 0.1: NIR up to 1.9, reflectance factors (ndvi_strata refuses values that cannot be); no
    # water or shadow test, so that every valid pixel is binned.
    image = _image(0.1 * np.ones_like(values), 0.1 * (1 + values) / (1 - values))
    strata = ndvi_strata(_lazy(image, 16), percentiles=(20, 40, 60, 80), water=(), shadow_reflectance=None)
    valid = values[np.isfinite(values)]
    # Edges: numpy's (linear) percentiles of the valid NDVI, to the 1e-4 NDVI histogram resolution.
    np.testing.assert_allclose(strata.edges, np.percentile(valid, [20, 40, 60, 80]), atol=2e-4)
    assert isinstance(strata.classes.data, da.Array)  # the classes stay lazy after the edges pass
    counts = np.bincount(strata.classes.values.ravel(), minlength=6)
    assert counts[0] == np.isnan(values).sum()
    assert np.all(np.abs(counts[1:] - valid.size / 5) <= 2), counts
    assert strata.classes.attrs["ndvi_percentiles"] == "20,40,60,80"


def test_masks_nodata_water_shadow():
    # Pixels: vegetation; blue NaN (nodata); clear water (NDVI -0.2, NIR 0.02: Fmask NDVI < 0.01 and
    # NIR < 0.11); turbid water (NDVI 0.08, NIR 0.04: Fmask NDVI < 0.1 and NIR < 0.05); shadow
    # (NDVI 0.2, (red + NIR) / 2 = 0.025 < 0.03); dark soil in the sun (NDVI 0.05, NIR 0.21).
    red = [0.04, 0.04, 0.03, 0.034, 0.02, 0.19]
    nir = [0.40, 0.40, 0.02, 0.04, 0.03, 0.21]
    visible = [0.05, np.nan, 0.03, 0.04, 0.02, 0.15]
    image = _image(red, nir, visible=visible)
    np.testing.assert_allclose(ndvi(image).values[0, 2:5], [-0.2, 0.0810810, 0.2], atol=1e-6)
    masked = ndvi_strata(image)
    np.testing.assert_array_equal(masked.classes.values[0], [5, 0, 0, 0, 0, 1])
    dedicated = ndvi_strata(image, water_id=6, shadow_id=7)
    np.testing.assert_array_equal(dedicated.classes.values[0], [5, 0, 6, 6, 7, 1])
    assert dedicated.names[6] == "water" and dedicated.names[7] == "shadow"
    unmasked = ndvi_strata(image, water=(), shadow_reflectance=None)
    np.testing.assert_array_equal(unmasked.classes.values[0], [5, 0, 1, 1, 2, 1])


def test_strata_bad_arguments():
    image = _with_ndvi([0.5])
    with pytest.raises(InputError, match="not both"):
        ndvi_strata(image, edges=(0.2,), percentiles=(50,))
    with pytest.raises(InputError, match="strictly increasing"):
        ndvi_strata(image, edges=(0.5, 0.2))
    with pytest.raises(InputError, match="water_id 3 must be 0"):
        ndvi_strata(image, edges=(0.2, 0.4), water_id=3)
    with pytest.raises(InputError, match="no pixel left"):
        ndvi_strata(_image([np.nan], [0.4]), percentiles=(50,))


def test_everything_stays_lazy(no_compute):
    image = _lazy(_with_ndvi(np.linspace(-0.5, 1.0, 24).reshape(4, 6)), 3)
    class_map = _lazy(georeference(xr.DataArray(np.ones((4, 6), np.uint8), dims=("y", "x"))), 3)
    results = [ndvi(image), ndvi_strata(image).classes, remap_classes(class_map, {1: 2}),
               align_class_map(class_map, image, lookup={1: 2})]
    assert all(isinstance(result.data, da.Array) for result in results)
    with pytest.raises(AssertionError, match="computed"):
        results[1].values  # the guard works
    assert results[-1].chunks == image.isel(band=0).chunks  # the image's chunks
    np.testing.assert_array_equal(results[-1].compute(scheduler="sync").values, 2)


# -- remapping ----------------------------------------------------------------------------------

def test_worldcover_codes():
    # ESA WorldCover 10 m 2020 v100 / 2021 v200 Product User Manual, legend table.
    assert sorted(WORLDCOVER_CODES) == [10, 20, 30, 40, 50, 60, 70, 80, 90, 95, 100]
    assert WORLDCOVER_CODES[80] == "Permanent water bodies" and WORLDCOVER_CODES[95] == "Mangroves"


@pytest.mark.parametrize("lazy", [False, True])
def test_remap_with_unknown_codes_and_nodata(lazy):
    codes = np.array([[10, 20, 30, 80], [0, 255, 45, 10]], dtype=np.uint8)  # 255 nodata, 45 unknown
    classes = georeference(xr.DataArray(codes, dims=("y", "x"))).rio.write_nodata(255)
    classes = _lazy(classes, 2) if lazy else classes
    lookup = {10: 1, 20: 2, 30: 2, 80: 5}
    remapped = remap_classes(classes, lookup, default=9)
    assert isinstance(remapped.data, da.Array) == lazy
    np.testing.assert_array_equal(remapped.values, [[1, 2, 2, 5], [0, 0, 9, 1]])
    np.testing.assert_array_equal(remap_classes(classes, lookup).values, [[1, 2, 2, 5], [0, 0, 0, 1]])
    assert remapped.dtype == np.uint8 and remapped.rio.nodata == 0 and remapped.rio.crs == classes.rio.crs
    assert remap_classes(classes, {10: 300}).dtype == np.uint16
    with pytest.raises(InputError, match="integers in 0..65535"):
        remap_classes(classes, {10: -1})
    with pytest.raises(InputError, match="integer class ids"):
        remap_classes(classes.astype(float), lookup)


# -- alignment ----------------------------------------------------------------------------------

def _target(ny=12, nx=16):
    return _with_ndvi(np.zeros((ny, nx)))


def test_align_finer_and_coarser_maps_in_the_same_crs():
    rng = np.random.default_rng(5)
    image = _target()
    coarse = rng.integers(1, 10, size=(12, 16)).astype(np.uint8)
    # 2x finer (5 m), constant within each 2x2 block: nearest neighbour gives the image-grid map back.
    coarse[3, 5] = 255  # nodata -> 0 (no class)
    fine = _grid(np.kron(coarse, np.ones((2, 2), np.uint8)), PIXEL / 2, nodata=255)
    aligned = align_class_map(fine, image)
    np.testing.assert_array_equal(aligned.values, np.where(coarse == 255, 0, coarse))
    assert aligned.dtype == np.uint8 and aligned.rio.nodata == 0
    assert aligned.rio.transform() == image.rio.transform() and aligned.rio.crs == image.rio.crs
    assert aligned.attrs["resampled_from_resolution"] == "5 x 5 metre"
    assert aligned.attrs["resampled_from_crs"] == "EPSG:32632"
    # 2x coarser (20 m): each 10 m pixel takes the 20 m cell its centre lies in.
    twenty = rng.integers(1, 10, size=(6, 8)).astype(np.uint16)
    twenty[2, 3] = 0xFFFF
    aligned = align_class_map(_lazy(_grid(twenty, 2 * PIXEL, nodata=0xFFFF), 3), _lazy(image, 5))
    expected = np.kron(twenty, np.ones((2, 2), np.uint16))
    expected[expected == 0xFFFF] = 0  # nodata -> 0 (no class)
    np.testing.assert_array_equal(aligned.values, expected)
    assert aligned.dtype == np.uint16


def test_an_aligned_map_keeps_what_it_says_of_its_classes():
    # NDVI strata aligned (onto their own grid, even) lost their tags: fit-classes then fitted
    # torrance_sparrow and named the classes class_1, ... instead of ross_thick_li_sparse and ndvi_...
    image = _target()
    strata = _grid(np.kron(np.array([[1, 2], [3, 1]], np.uint8), np.ones((6, 8), np.uint8)), PIXEL)
    strata.attrs.update({"strata": "ndvi_edges", "ndvi_edges": "0.3,0.6", "class_names": "1=ndvi_-inf_0.30"})
    aligned = align_class_map(strata, image)
    assert {key: aligned.attrs[key] for key in ("strata", "ndvi_edges", "class_names")} == {
        "strata": "ndvi_edges", "ndvi_edges": "0.3,0.6", "class_names": "1=ndvi_-inf_0.30"}
    remapped = align_class_map(strata, image, lookup={1: 5, 2: 6, 3: 7})  # other ids: the names do not hold
    assert "class_names" not in remapped.attrs and "strata" not in remapped.attrs


def test_align_from_geographic_crs_lands_at_known_locations():
    image = _target(20, 24)  # UTM 32N near 9 E, 48.8 N (brdfcorr.testing)
    to_lonlat = Transformer.from_crs(CRS, "EPSG:4326", always_xy=True)
    west, south, east, north = (image.rio.transform_bounds("EPSG:4326"))
    res, margin = 0.0002, 0.001  # ~15 m x 22 m cells [deg]
    origin = (west - margin, north + margin)
    ny, nx = int((north - south + 2 * margin) / res) + 1, int((east - west + 2 * margin) / res) + 1
    codes = np.random.default_rng(7).integers(1, 10, size=(ny, nx)).astype(np.uint8)
    codes[::3, ::4] = 200  # nodata cells
    lookup = {code: code + 10 for code in range(1, 10)}
    aligned = align_class_map(_grid(codes, res, origin=origin, crs="EPSG:4326", nodata=200), image, lookup)
    # Independently: the geographic cell holding each image pixel centre.
    x, y = np.meshgrid(image.x.values, image.y.values)
    lon, lat = to_lonlat.transform(x, y)
    col, row = (lon - origin[0]) / res, (origin[1] - lat) / res
    expected = codes[row.astype(int), col.astype(int)].astype(int)
    expected = np.where(expected == 200, 0, expected + 10)
    # Only centres clear of the cell edges: GDAL's approximate transformer may err 0.125 pixel.
    clear = (np.abs(col % 1 - 0.5) < 0.35) & (np.abs(row % 1 - 0.5) < 0.35)
    assert clear.mean() > 0.4
    np.testing.assert_array_equal(aligned.values[clear], expected[clear])
    assert aligned.attrs["resampled_from_crs"] == "EPSG:4326"
    assert aligned.attrs["resampled_from_resolution"] == "0.0002 x 0.0002 degree"
    assert aligned.attrs["class_lookup"].startswith("1:11,2:12")


def test_a_lookup_of_code_0_holds_on_an_aligned_map_as_on_one_on_the_image_grid():
    # MODIS land cover's code 0 is water, a class: with the lookup 0 -> 4 it is class 4 whether
    # the map needs aligning or not (it was "no class" once aligned: the warp's fill is 0 too);
    # the map's nodata (255) and places it does not reach stay 0.
    image = _target(8, 10)
    codes = np.tile(np.array([0, 10, 20, 255], dtype=np.uint8), (8, 3))[:, :10]
    class_map = _grid(codes, PIXEL, nodata=255)
    lookup = {0: 4, 10: 1, 20: 2}
    expected = np.select([codes == 0, codes == 10, codes == 20], [4, 1, 2], 0)
    np.testing.assert_array_equal(remap_classes(class_map, lookup).values, expected)
    np.testing.assert_array_equal(align_class_map(class_map, image, lookup).values, expected)


def test_align_partial_cover_gives_no_class_where_the_map_does_not_reach():
    image = _lazy(_target(), 4)
    left = _grid(np.full((12, 6), 3, np.uint8), PIXEL)  # the 6 left columns of the image grid only
    aligned = align_class_map(left, image).values
    np.testing.assert_array_equal(aligned[:, :6], 3)
    np.testing.assert_array_equal(aligned[:, 6:], 0)


def test_align_errors():
    image = _target()
    far = _grid(np.ones((4, 4), np.uint8), PIXEL, origin=(ORIGIN[0] + 1e5, ORIGIN[1]))
    with pytest.raises(InputError, match="does not overlap"):
        align_class_map(far, image)
    no_crs = xr.DataArray(np.ones((12, 16), np.uint8), dims=("y", "x"),
                          coords={"y": image.y.values, "x": image.x.values})
    with pytest.raises(InputError, match="class map has no CRS"):
        align_class_map(no_crs, image)


# -- what the image holds -----------------------------------------------------------------------

def _scene_with_water_and_shadow() -> xr.DataArray:
    """Reflectance with land over NDVI -0.2..0.9, water (NDVI < 0 with NIR < 0.11) and shadow
    ((red + NIR) / 2 < 0.03)."""
    rng = np.random.default_rng(5)
    values = rng.uniform(-0.2, 0.9, size=(30, 40))
    nir = rng.uniform(0.15, 0.6, size=values.shape)
    nir[:5], values[:5] = 0.03, -0.3  # water: red 0.056
    nir[5:10] = rng.uniform(0.01, 0.02, size=(5, 40))  # shadow
    return _image(nir * (1 - values) / (1 + values), nir)


@pytest.mark.parametrize("lazy", [False, True])
def test_counts_with_their_scale_and_offset_give_the_strata_of_their_reflectance(lazy):
    # Sentinel-2 L2A from baseline 04.00: reflectance = counts * 0.0001 - 0.1. Taken as they are,
    # the offset would change NDVI and counts would pass no water or shadow test.
    factors = _scene_with_water_and_shadow()
    counts = np.round((factors + 0.1) / 1e-4).astype(np.uint16)
    counts.attrs.update(scale_factor=1e-4, add_offset=-0.1)
    stored = counts.copy(data=counts.values * 1e-4 - 0.1)  # what the counts stand for
    stored.attrs = {}
    expected = ndvi_strata(stored, water_id=7, shadow_id=8).classes.values
    counts = _lazy(counts, 16) if lazy else counts
    np.testing.assert_array_equal(ndvi_strata(counts, water_id=7, shadow_id=8).classes.values, expected)
    assert {7, 8} <= set(np.unique(expected))  # both tests fire
    np.testing.assert_allclose(ndvi(counts).values, ndvi(stored).values, atol=1e-5)  # counts scaled in float32


def test_percent_reflectance_is_refused_numpy_at_once_dask_when_computed(no_compute):
    percent = _scene_with_water_and_shadow() * 100
    with pytest.raises(InputError, match="the values do not look like reflectance factors"):
        ndvi_strata(percent)
    lazy = ndvi_strata(_lazy(percent, 16))  # no read: the check runs with each chunk
    with pytest.raises(InputError, match=r"99th percentile [0-9.]+ .*raw counts\? Or reflectance x 10000"):
        lazy.classes.compute(scheduler="sync")


def test_pixels_on_a_bin_edge_fall_in_the_bin_the_float64_ndvi_gives():
    # float32 reflectance whose NDVI is an edge: the bins are left-closed, and the NDVI computed in
    # float32 falls below the edge for some of them (19 of 48 before the float64 arithmetic).
    rng = np.random.default_rng(11)
    edges = np.asarray(DEFAULT_EDGES)
    red = rng.uniform(0.02, 0.3, size=(len(edges), 48)).astype(np.float32)
    nir = (red * (1 + edges[:, None]) / (1 - edges[:, None])).astype(np.float32)
    image = _image(red, nir).astype(np.float32)
    red64, nir64 = red.astype(np.float64), nir.astype(np.float64)
    expected = np.digitize((nir64 - red64) / (nir64 + red64), edges) + 1  # the independent float64 NDVI
    classes = ndvi_strata(image, water=(), shadow_reflectance=None).classes.values
    np.testing.assert_array_equal(classes, expected)
