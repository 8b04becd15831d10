"""Integer outputs encoded in the writing pass (issue 28): ``encode_integers`` stays lazy, one task
per chunk, and gives what the definition ``stored = round((reflectance - offset) / scale)`` gives,
computed here independently in float64 with numpy; ``correct --output-type input`` computes the
correction once (as many dask passes as the float output), with the out-of-range count from that pass."""

from __future__ import annotations

import dask
import dask.array as da
import numpy as np
import pytest
import rasterio
import xarray as xr
from dask.callbacks import Callback

from brdfcorr.io.scene import SceneSources
from brdfcorr.io.writer import encode_integers
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles
from brdfcorr.testing import synthetic_scene


def _expected(values: np.ndarray, dtype, scales, offsets, nodata):
    """The definition, computed on the whole cube at once: round half to even in float64; NaN,
    values outside the type and values on ``nodata`` become ``nodata``."""
    info = np.iinfo(dtype)
    stored = np.round((values.astype(np.float64) - offsets[:, None, None]) / scales[:, None, None])
    outside = (stored < info.min) | (stored > info.max) | (stored == nodata)
    encoded = np.where(~outside & ~np.isnan(stored), stored, nodata).astype(dtype)
    return encoded, outside.any(axis=0)


def _cube(dtype) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """4 bands x 12 x 10 float32 with the edge cases: the type's bounds and one past them, halves
    (as far as float32 keeps them), NaN and infinities."""
    rng = np.random.default_rng(28)
    scales, offsets = np.array([1e-4, 2e-4, 1e-3, 0.004]), np.array([0.0, -0.1, 0.0, 0.05])
    info = np.iinfo(dtype)
    counts = rng.uniform(info.min, info.max, size=(4, 12, 10))
    counts[:, 0, :6] = [info.min - 1, info.min, info.max, info.max + 1, 2.5, 3.5]
    values = counts * scales[:, None, None] + offsets[:, None, None]
    values[:, 1, :3] = [np.nan, np.inf, -np.inf]
    return values.astype(np.float32), scales, offsets


@pytest.mark.parametrize(("dtype", "nodata"), [("int16", -9999), ("uint8", 255), ("uint16", None), ("int32", 0)])
def test_encoding_matches_the_definition_and_stays_lazy(dtype, nodata, no_compute):
    values, scales, offsets = _cube(dtype)
    # chunks across bands too: each chunk must be given its own bands' scales and offsets
    data = da.from_array(values, chunks=(3, 5, 4))
    array = xr.DataArray(data, dims=("band", "y", "x"), coords={"band": [1, 2, 3, 4]}, attrs={"units": "1"})
    encoded, out_of_range = encode_integers(array, dtype, scales, offsets, nodata)  # no_compute: lazy
    fill = encoded.rio.nodata
    assert fill == (nodata if nodata is not None else (np.iinfo(dtype).min if dtype[0] == "i" else np.iinfo(dtype).max))
    with dask.config.set(scheduler="synchronous"):
        stored, flagged = encoded.values, out_of_range.values
    expected, outside = _expected(values, dtype, scales, offsets, fill)
    assert stored.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(stored, expected)
    np.testing.assert_array_equal(flagged, outside)
    assert flagged[0, 0] and flagged[0, 3] and not flagged[0, 4:6].any()  # one past the bounds; halves fit
    assert flagged[1, 1] and flagged[1, 2] and not flagged[1, 0]  # +-inf do not fit; NaN is nodata, not flagged
    assert encoded.attrs["scales"] == tuple(scales) and encoded.attrs["offsets"] == tuple(offsets)


def test_numpy_input_gives_the_same_integers():
    values, scales, offsets = _cube("int16")
    array = xr.DataArray(values, dims=("band", "y", "x"))
    encoded, out_of_range = encode_integers(array, "int16", scales, offsets, -9999)
    expected, outside = _expected(values, "int16", scales, offsets, -9999)
    np.testing.assert_array_equal(encoded.values, expected)
    np.testing.assert_array_equal(out_of_range.values, outside)


class _Passes(Callback):
    """Counts the dask computations (passes) started while active."""

    def __init__(self):
        super().__init__()
        self.count = 0

    def _start(self, dsk):
        self.count += 1


@pytest.fixture(scope="module")
def int_scene(tmp_path_factory, write_example_scene):
    """A synthetic scene stored as uint8 at 0.004 per count (nodata 255): bright enough that some
    corrected values exceed the type."""
    directory = tmp_path_factory.mktemp("encoding")
    paths = write_example_scene(directory, synthetic_scene(ny=32, nx=48))
    with rasterio.open(paths["image"]) as dataset:
        profile, values, descriptions = dataset.profile, dataset.read(), dataset.descriptions
    rng = np.random.default_rng(5)
    counts = np.where(np.isfinite(values), rng.integers(230, 251, size=values.shape), 255)
    profile.update(dtype="uint8", nodata=255)
    paths["stored"] = directory / "stored.tif"
    with rasterio.open(paths["stored"], "w", **profile) as dataset:
        dataset.write(counts.astype("uint8"))
        dataset.descriptions, dataset.scales = descriptions, (0.004,) * len(descriptions)
    return paths


def _run(paths, output, data_type):
    passes = _Passes()
    with passes:
        result = correct_files(CorrectionRequest(
            SceneSources(paths["stored"], paths["classes"], paths["angles"]), paths["params"],
            OutputFiles(output, qa=output.with_suffix(".qa.tif"), data_type=data_type), reference={"sza": 35.0},
            engine=Engine(chunks=16, scheduler="synchronous"),
        ))
    return result, passes.count


def test_integer_output_takes_no_extra_pass(int_scene, tmp_path):
    floats, float_passes = _run(int_scene, tmp_path / "float.tif", "float")
    integers, integer_passes = _run(int_scene, tmp_path / "int.tif", "input")
    assert integer_passes == float_passes  # the correction is computed once, in the writing pass
    assert "out_of_range" not in floats.counts
    with rasterio.open(tmp_path / "float.tif") as reference, rasterio.open(tmp_path / "int.qa.tif") as qa:
        counts = np.round(reference.read().astype(np.float64) / 0.004)
        flags = qa.read(1)
    beyond = (np.isfinite(counts) & (counts >= 255)).any(axis=0) & np.isfinite(counts).all(axis=0)
    assert 0 < integers.counts["out_of_range"] == beyond.sum()  # independent: the float output's counts
    assert np.all(flags[beyond] & 1)  # flagged nodata
    assert integers.counts["nodata"] == floats.counts["nodata"] + integers.counts["out_of_range"]
