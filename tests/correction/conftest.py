"""Fixtures of the correction tests: a small image with its angles on a coarse grid of nodes."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from affine import Affine

from brdfcorr.io.sensors.grids import to_grid

#: The coarse grid of the angles (100 m between nodes) and the image's 20 m pixels: every fifth
#: pixel (rows and columns 2, 7, 12, ...) is centred on a node.
NODES = Affine(100.0, 0.0, 0.0, 0.0, -100.0, 500.0)
PIXELS = Affine(20.0, 0.0, 0.0, 0.0, -20.0, 500.0)


def _on_grid(values: np.ndarray, transform: Affine) -> xr.DataArray:
    rows, cols = values.shape
    array = xr.DataArray(values, dims=("y", "x"), coords={"y": transform.f + transform.e * (np.arange(rows) + 0.5),
                                                           "x": transform.c + transform.a * (np.arange(cols) + 0.5)})
    return array.rio.write_crs("EPSG:32633").rio.write_transform(transform)


def _node_scene(coarse: dict[str, np.ndarray], data: np.ndarray) -> tuple[xr.DataArray, dict[str, xr.DataArray]]:
    image = _on_grid(np.zeros(data.shape[1:]), PIXELS).expand_dims(band=data.shape[0])
    image = image.assign_coords(wavelength=("band", [490.0, 665.0, 842.0][:data.shape[0]]))
    image = image.copy(data=data).chunk({"y": 16, "x": 16})
    angles = {name: to_grid(_on_grid(values, NODES), image, angle=name.endswith("aa"), chunks=(16, 16))
              for name, values in coarse.items()}
    return image, angles


@pytest.fixture(scope="session")
def node_scene():
    """``node_scene(coarse, data)``: the image ``data`` (band, y, x; 25 x 30 pixels of 20 m,
    wavelengths 490, 665 and 842 nm, chunks of 16) and the angle grids ``coarse`` (name: 5 x 6
    nodes 100 m apart [deg]) interpolated to its pixels by the sensor readers'
    :func:`brdfcorr.io.sensors.grids.to_grid`."""
    return _node_scene
