"""A few pixels of an interpolated angle grid from its coarse grid alone (grids.grid_window,
angles.window_values): the same values as the computed layer, without computing a chunk."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from affine import Affine

from brdfcorr.io.angles import window_values
from brdfcorr.io.sensors.grids import grid_template, grid_window, to_grid

COARSE = Affine(100.0, 0.0, 1000.0, 0.0, -100.0, 5000.0)


def _coarse(values: np.ndarray) -> xr.DataArray:
    rows, cols = values.shape
    x = COARSE.c + COARSE.a * (np.arange(cols) + 0.5)
    y = COARSE.f + COARSE.e * (np.arange(rows) + 0.5)
    array = xr.DataArray(values, dims=("y", "x"), coords={"y": y, "x": x})
    return array.rio.write_transform(COARSE).rio.write_crs("EPSG:32611")


@pytest.mark.parametrize("angle, low, high", [(False, 0.0, 60.0), (True, 0.0, 360.0)])
def test_window_equals_the_computed_layer(angle, low, high):
    # Property: the window is the same bilinear interpolation as the chunk's (bit for bit), here
    # straddling chunk borders (chunks of 17) and the clamped edge beyond the outermost centres.
    values = np.random.default_rng(3).uniform(low, high, (5, 6))
    like = grid_template(Affine(10.0, 0, 1000.0, 0, -10.0, 5000.0), (50, 60), "EPSG:32611", chunks=17)
    layer = to_grid(_coarse(values), like, angle=angle)
    rows, cols = slice(0, 20), slice(30, 60)
    window = grid_window(layer, rows, cols)
    assert window is not None and window.shape == (20, 30)
    np.testing.assert_array_equal(window, layer.values[rows, cols])
    np.testing.assert_array_equal(window_values(layer, rows, cols), window)


def test_without_a_record_the_layer_is_read():
    # A subset no longer has the grid the record was made for: no shortcut, the layer's own values.
    values = np.random.default_rng(4).uniform(0.0, 60.0, (5, 6))
    like = grid_template(Affine(10.0, 0, 1000.0, 0, -10.0, 5000.0), (50, 60), "EPSG:32611", chunks=17)
    layer = to_grid(_coarse(values), like)
    subset = layer.isel(y=slice(10, 40))
    subset.encoding = dict(layer.encoding)  # a record that travelled with a subset is ignored
    assert grid_window(subset, slice(0, 4), slice(0, 4)) is None
    np.testing.assert_array_equal(window_values(subset, slice(0, 4), slice(0, 4)), layer.values[10:14, 0:4])


def test_view_vector_layers_window_and_reprojected_path_agree():
    """A view direction given as its ground-projected vector (2, y, x): the window equals the computed
    layer, and the per-pixel (reprojection) path gives the separable path's values on one grid."""
    from brdfcorr.io.sensors.grids import view_angles, view_vector

    rng = np.random.default_rng(5)
    zenith, azimuth = rng.uniform(0.0, 12.0, (5, 6)), rng.uniform(0.0, 360.0, (5, 6))
    coarse = xr.concat([_coarse(component) for component in view_vector(zenith, azimuth)], dim="component")
    like = grid_template(Affine(10.0, 0, 1000.0, 0, -10.0, 5000.0), (50, 60), "EPSG:32611", chunks=17)
    for kind, index in (("view_zenith", 0), ("view_azimuth", 1)):
        layer = to_grid(coarse, like, angle=kind)
        window = grid_window(layer, slice(0, 20), slice(30, 60))
        np.testing.assert_array_equal(window, layer.values[:20, 30:60])
        # The angles of the components interpolated as plain grids.
        east, north = (to_grid(coarse[component], like).values for component in (0, 1))
        np.testing.assert_allclose(layer.values, view_angles(np.stack([east, north]))[index], atol=1e-9)
        rotated = like.rio.write_transform(Affine(10.0, 1e-12, 1000.0, 0, -10.0, 5000.0))  # not axis-aligned
        np.testing.assert_allclose(to_grid(coarse, rotated, angle=kind).values, layer.values, atol=1e-6)
