"""Lazy interpolation of coarse angle grids onto image grids."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import xarray as xr
from affine import Affine
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import RegularGridInterpolator

from brdfcorr.errors import SensorInputError
from brdfcorr.io.sensors.grids import grid_template, to_grid

COARSE = Affine(100.0, 0.0, 1000.0, 0.0, -100.0, 5000.0)


def coarse_grid(values: np.ndarray, transform: Affine = COARSE, crs="EPSG:32611") -> xr.DataArray:
    rows, cols = values.shape
    x = transform.c + transform.a * (np.arange(cols) + 0.5)
    y = transform.f + transform.e * (np.arange(rows) + 0.5)
    array = xr.DataArray(values, dims=("y", "x"), coords={"y": y, "x": x})
    array = array.rio.write_transform(transform)
    return array.rio.write_crs(crs) if crs else array


def test_bilinear_between_pixel_centres_matches_scipy():
    values = np.random.default_rng(1).uniform(0, 60, (5, 6))
    coarse = coarse_grid(values)
    like = grid_template(Affine(10.0, 0, 1000.0, 0, -10.0, 5000.0), (50, 60), "EPSG:32611", chunks=17)
    out = to_grid(coarse, like, name="sza", attrs={"units": "degree"})
    assert isinstance(out.data, da.Array) and out.data.chunks == like.data.chunks
    assert out.name == "sza" and out.attrs == {"units": "degree"} and out.rio.crs.to_epsg() == 32611
    reference = RegularGridInterpolator((coarse.y.values[::-1], coarse.x.values), values[::-1])
    yy, xx = np.meshgrid(like.y.values, like.x.values, indexing="ij")
    inside = (yy >= coarse.y.min().item()) & (yy <= coarse.y.max().item()) & \
             (xx >= coarse.x.min().item()) & (xx <= coarse.x.max().item())
    computed = out.values
    np.testing.assert_allclose(computed[inside], reference((yy[inside], xx[inside])), rtol=0, atol=1e-12)
    # Beyond the outermost centres the edge value is held: row 0 of the output (y = 4995) lies
    # above the first coarse centre row (y = 4950), so it equals the interpolation along that row.
    np.testing.assert_allclose(computed[0, 5:55], reference((np.full(50, 4950.0), like.x.values[5:55])))


def test_azimuth_interpolated_through_sine_and_cosine():
    # Two columns of azimuths 350 and 10 deg: halfway is 0 deg (north), never 180 deg.
    values = np.array([[350.0, 10.0], [350.0, 10.0]])
    coarse = coarse_grid(values, Affine(100.0, 0, 0, 0, -100.0, 200.0))
    like = grid_template(Affine(25.0, 0, 37.5, 0, -25.0, 200.0), (8, 4), "EPSG:32611")
    out = to_grid(coarse, like, angle=True).values
    # Pixel centres x = 50 (the 350 deg node), 75 (a quarter of the way), 100 (halfway).
    assert out[1, 0] == pytest.approx(350.0, abs=1e-9)
    # Quarter way: atan2(0.75 sin 350 + 0.25 sin 10, 0.75 cos 350 + 0.25 cos 10) = -5.04 deg.
    assert out[1, 1] == pytest.approx(354.96, abs=0.01)
    assert min(out[1, 2], 360.0 - out[1, 2]) == pytest.approx(0.0, abs=1e-9)
    assert ((out >= 0) & (out < 360)).all()
    linear = to_grid(coarse, like, angle=False).values
    assert linear[1, 2] == pytest.approx(180.0)  # what a plain linear interpolation would do


@settings(max_examples=25, deadline=None)
@given(azimuth=st.floats(0, 359.999), zenith=st.floats(0, 89))
def test_constant_grids_stay_constant(azimuth, zenith):
    like = grid_template(Affine(7.0, 0, 1003.0, 0, -7.0, 4900.0), (9, 11), "EPSG:32611", chunks=4)  # on the grid
    for value, angle in ((azimuth, True), (zenith, False)):
        out = to_grid(coarse_grid(np.full((3, 4), value)), like, angle=angle).values
        difference = (out - value + 180.0) % 360.0 - 180.0 if angle else out - value
        np.testing.assert_allclose(difference, 0.0, atol=1e-9)


def test_reprojection_to_another_crs_is_lazy_and_linear_field_exact():
    # A field linear in the coarse grid's map coordinates is reproduced exactly (bilinear is
    # exact for linear fields) at the target pixel centres transformed back with pyproj.
    import pyproj

    transform = Affine(5000.0, 0, 300000.0, 0, -5000.0, 5_100_000.0)
    cols, rows = np.meshgrid(np.arange(20) + 0.5, np.arange(20) + 0.5)
    x, y = transform @ (cols, rows)
    coarse = coarse_grid(30.0 + 1e-5 * (x - 300000.0) - 2e-5 * (5_100_000.0 - y), transform, "EPSG:32633")
    like = grid_template(Affine(0.01, 0, 13.2, 0, -0.01, 46.0), (30, 40), "EPSG:4326", chunks=16)
    out = to_grid(coarse, like)
    assert isinstance(out.data, da.Array) and out.data.npartitions == 6
    lon, lat = np.meshgrid(like.x.values, like.y.values)
    ux, uy = pyproj.Transformer.from_crs(4326, 32633, always_xy=True).transform(lon, lat)
    np.testing.assert_allclose(out.values, 30.0 + 1e-5 * (ux - 300000.0) - 2e-5 * (5_100_000.0 - uy), atol=1e-9)


def test_full_resolution_is_never_materialized():
    # A 10 m Sentinel-2-sized grid: building it costs nothing, one window computes alone.
    like = grid_template(Affine(10.0, 0, 300000.0, 0, -10.0, 8600020.0), (10980, 10980), "EPSG:32723")
    out = to_grid(coarse_grid(np.arange(529.0).reshape(23, 23), Affine(5000.0, 0, 297500.0, 0, -5000.0, 8602520.0),
                              "EPSG:32723"), like)
    assert out.data.npartitions == 36 and out.nbytes == 10980 * 10980 * 8
    window = out.isel(y=slice(5000, 5003), x=slice(0, 2)).values
    assert window.shape == (3, 2)


def test_crs_on_one_side_only_is_refused():
    like = grid_template(Affine(10.0, 0, 1000.0, 0, -10.0, 5000.0), (5, 5), None)
    with pytest.raises(SensorInputError, match="only one of them has a CRS"):
        to_grid(coarse_grid(np.ones((3, 3))), like)
