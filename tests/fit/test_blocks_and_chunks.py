"""The imagery fit's spatial blocks (``fit-classes --block-size``: the clusters of its robust errors
and the folds of ``auto``'s held-out choice) are squares of the scene, row // block and
column // block counted from its first pixel, not pieces of a dask chunk (as for ``assess``, whose
blocks were once cut at chunk edges: brdfcorr.analysis.view_angle_sums).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from brdfcorr.fit.sampling import sample_classes
from brdfcorr.fit.settings import Sampling

BLOCK = 24  # not a multiple of the chunks below: blocks straddle their edges


def test_sample_blocks_are_numbered_in_the_scene():
    # Angles that encode each pixel's place (sza = 10 + row / 10, vza = column / 10 [deg]): the
    # block of each sample, computed from its place, is its label, with chunks of 16 x 20 pixels.
    ny, nx = 70, 90
    rows, columns = np.mgrid[0:ny, 0:nx].astype(float)
    angles = xr.Dataset({"sza": (("y", "x"), 10 + rows / 10), "vza": (("y", "x"), columns / 10),
                         "saa": (("y", "x"), np.full((ny, nx), 150.0)), "vaa": (("y", "x"), np.full((ny, nx), 90.0))})
    image = xr.DataArray(np.full((2, ny, nx), 0.2), dims=("band", "y", "x")).chunk({"y": 16, "x": 20})
    classes = xr.DataArray(np.ones((ny, nx), np.uint8), dims=("y", "x"))
    samples = sample_classes(image, classes, angles.chunk({"y": 16, "x": 20}),
                             sampling=Sampling(max_samples=2000, block_size=BLOCK, bad_bands=()))[1]
    row, column = np.round((samples.theta_i - 10) * 10), np.round(samples.theta_r * 10)
    blocks_per_row = -(-nx // BLOCK)  # 4
    assert samples.block.size == 2000
    np.testing.assert_array_equal(samples.block, (row // BLOCK) * blocks_per_row + column // BLOCK)

