"""The chain's quicklook shows both panels in reflectance factors under one stretch: an input of
scaled integer counts (GDAL scale 1e-4) was drawn as counts beside the corrected reflectance, so
the shared stretch left the "after" panel black."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin

import brdfcorr.chain.quicklook as chain_quicklook


def _write(path, data, dtype, tags=None, scales=None, offsets=None):
    profile = {"driver": "GTiff", "width": data.shape[2], "height": data.shape[1], "count": data.shape[0],
               "dtype": dtype, "crs": "EPSG:32633", "transform": from_origin(500000, 4000000, 10, 10)}
    with rasterio.open(path, "w", **profile) as dataset:
        dataset.write(data.astype(dtype))
        dataset.update_tags(**(tags or {}))
        if scales is not None:
            dataset.scales, dataset.offsets = scales, offsets
    return path


@pytest.mark.parametrize("output_type", ["float", "input"])
def test_an_input_of_scaled_counts_is_drawn_as_the_reflectance_the_correction_read(tmp_path, monkeypatch,
                                                                                   output_type):
    counts = np.random.default_rng(0).integers(400, 3000, size=(3, 20, 24))
    image = _write(tmp_path / "image.tif", counts, "int16", scales=(1e-4,) * 3, offsets=(-0.05,) * 3)
    reflectance = counts * 1e-4 - 0.05  # what the correction read (its tags record the scaling)
    tags = {"brdf_input_scale": "0.0001", "brdf_input_offset": "-0.05", "wavelength": "480,560,660"}
    if output_type == "float":
        corrected = _write(tmp_path / "corrected.tif", reflectance * 1.01, "float32", tags)
    else:  # --output-type input: the input's counts, scale and offset
        corrected = _write(tmp_path / "corrected.tif", np.round((reflectance * 1.01 + 0.05) / 1e-4), "int16", tags,
                           scales=(1e-4,) * 3, offsets=(-0.05,) * 3)
    drawn = {}

    def spy(before, after, **kwargs):
        drawn.update(before=before, after=after)
        return original(before, after, **kwargs)

    original = chain_quicklook.quicklook_figure
    monkeypatch.setattr(chain_quicklook, "quicklook_figure", spy)
    chain_quicklook.write_quicklook(image, corrected, tmp_path / "quicklook.png", bands=[3, 2, 1])
    np.testing.assert_allclose(drawn["before"], reflectance[::-1], rtol=1e-6)
    np.testing.assert_allclose(drawn["after"], 1.01 * reflectance[::-1], rtol=1e-5, atol=0.5e-4)  # stored to 1e-4
