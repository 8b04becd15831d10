"""A 64-bit integer output cannot be written exactly: ``--output-type input`` for a uint64 or int64
image is refused (uint64 was exit 1; int64's nodata at its lowest value read back as -9) with exit
code 2, exactly one stderr line ``brdfcorr: error: ...`` naming the cause, no file in the output
directory and inputs unchanged; such an image still corrects to floats.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.io.writer import encode_integers
from brdfcorr.testing import georeference


def _integer_image(scene, dtype: str, nodata) -> Path:
    """The scene's image stored as ``dtype`` counts of 1e-4 (GDAL scale tags), nodata ``nodata``."""
    with rasterio.open(scene["image"]) as dataset:
        data, profile, descriptions = dataset.read(), dataset.profile, dataset.descriptions
    path = scene["dir"] / f"image_{dtype}_{'none' if nodata is None else 'nodata'}.tif"
    with rasterio.open(path, "w", **{**profile, "dtype": dtype, "nodata": nodata}) as target:
        target.write(np.round(data / 1e-4).astype(dtype))
        target.scales = (1e-4,) * profile["count"]
        target.descriptions = descriptions
    return path


@pytest.mark.parametrize("dtype, nodata", [
    ("uint64", None), ("uint64", 0), ("int64", None), ("int64", -9999), ("int64", -2**63),
])
def test_output_type_input_refuses_64_bit_integers(scene, dtype, nodata, refused, correct_args):
    image = _integer_image(scene, dtype, nodata)
    refused(scene, correct_args(scene, "--output-type", "input", image=image),
            rf"output type 'input' \(--output-type input\): image \S*{image.name} is stored as {dtype}, and a "
            r"64-bit integer output cannot be written exactly .* write floats \(--output-type float\)")


def test_a_64_bit_image_still_corrects_to_floats(scene, correct_args):
    image = _integer_image(scene, "uint64", None)
    result = CliRunner().invoke(main, [str(a) for a in correct_args(scene, "--output-type", "float", image=image)])
    assert result.exit_code == 0, result.output
    with rasterio.open(scene["output"]) as dataset:
        assert dataset.dtypes[0] == "float32"


@pytest.mark.parametrize("dtype", [np.int64, np.uint64])
def test_encode_integers_refuses_64_bit_types(dtype):
    array = georeference(xr.DataArray(np.full((1, 2, 2), 0.5), dims=("band", "y", "x")))
    with pytest.raises(InputError, match=f"{np.dtype(dtype)} cannot be written exactly"):
        encode_integers(array, dtype, 1e-4, 0.0)
