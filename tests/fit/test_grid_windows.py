"""The common grid held per scene window (issue 37, bounded memory): each scene's index layer covers
its footprint's box of the common grid only, and is, pixel for pixel, the whole-union layer that a
reprojection onto the union gives (computed here independently with rioxarray)."""

from __future__ import annotations

import numpy as np
import rioxarray  # noqa: F401  (registers .rio)
import xarray as xr
from affine import Affine
from rasterio.enums import Resampling

from brdfcorr.fit.grids import Window, common_grid

PIXEL, ORIGIN, CRS = 10.0, (500_000.0, 5_400_000.0), "EPSG:32632"


def _line(columns: float, rows: float, shape=(30, 20), pixel=PIXEL) -> xr.DataArray:
    """A one-band image on a grid ``columns``, ``rows`` pixels of 10 m east and south of ORIGIN."""
    x = ORIGIN[0] + PIXEL * columns + pixel * (np.arange(shape[1]) + 0.5)
    y = ORIGIN[1] - PIXEL * rows - pixel * (np.arange(shape[0]) + 0.5)
    image = xr.DataArray(np.ones((1, *shape), np.float32), dims=("band", "y", "x"),
                         coords={"band": [1], "x": x, "y": y}).rio.write_crs(CRS)
    return image.rio.write_transform(image.rio.transform(recalc=True))


def _whole(image: xr.DataArray, grid, transform: Affine) -> np.ndarray:
    """The image's source index over the whole union, by one reprojection onto it (as before windows)."""
    ny, nx = image.sizes["y"], image.sizes["x"]
    index = xr.DataArray(np.arange(ny * nx, dtype=np.int32).reshape(ny, nx), dims=("y", "x"),
                         coords={"y": image["y"].values, "x": image["x"].values})
    index = index.rio.write_crs(image.rio.crs).rio.write_transform(image.rio.transform()).rio.write_nodata(-1)
    moved = index.rio.reproject(CRS, shape=grid.shape, transform=transform, resampling=Resampling.nearest, nodata=-1)
    return np.asarray(moved.values, dtype=np.int32).reshape(-1)


def test_each_scenes_window_is_its_part_of_the_whole_union_layer():
    # A survey of long lines side by side (70 % of a line apart, sub-pixel shifts), one of 15 m pixels.
    lines = [_line(14.37 * number, 0.21 * number) for number in range(5)] + [_line(30.5, 3.3, (20, 14), 15.0)]
    grid = common_grid([line[0] for line in lines])
    transform = lines[0].rio.transform()  # the union starts at the first line's corner here
    assert grid.shape == (34, 78)
    for scene, line in enumerate(lines):
        np.testing.assert_array_equal(grid.sources[scene], _whole(line, grid, transform))
    window_pixels = sum(window.rows * window.cols for window in grid.windows)
    assert window_pixels < 0.5 * len(lines) * grid.shape[0] * grid.shape[1]  # held: the windows, not the union


def test_a_scene_in_another_crs_keeps_the_whole_grid():
    other = _line(5.0, 2.0).rio.reproject("EPSG:32633")
    grid = common_grid([_line(0.0, 0.0)[0], other[0]])
    assert grid.windows[1] == Window(0, 0, grid.shape[0], grid.shape[1], grid.shape)
    assert grid.windows[0].rows * grid.windows[0].cols < grid.shape[0] * grid.shape[1]


def test_window_layers_answer_as_the_whole_layer():
    lines = [_line(0.0, 0.0), _line(12.4, 1.7)]
    grid = common_grid([line[0] for line in lines])
    values = np.arange(30 * 20).reshape(30, 20) % 7
    for scene in range(2):
        layer = grid.gather(scene, values, -1)
        whole = np.where(grid.sources[scene] >= 0, values.reshape(-1)[np.maximum(grid.sources[scene], 0)], -1)
        mask = layer.values == 3
        flat = layer.flat_where(mask)
        np.testing.assert_array_equal(flat, np.flatnonzero(whole == 3))  # the same pixels, in the same order
        iy, ix = np.divmod(flat, grid.shape[1])
        np.testing.assert_array_equal(layer[iy, ix], whole[flat])
        np.testing.assert_array_equal(grid.windows[scene].from_common(flat), np.flatnonzero(mask))
        np.testing.assert_array_equal(grid.source_pixels(scene, flat), grid.sources[scene][flat])
