"""A DEM that gives no pixel a slope (nodata only, or valid pixels that are all isolated) leaves
nothing to correct: exit 2 naming the DEM, not an output of 100 % nodata with exit 0 (issue 26,
"an input that leaves nothing to correct is exit 2")."""

from __future__ import annotations

import dask.array as da
import numpy as np
import pytest
import xarray as xr
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.correction.terrain import check_dem_slope, slope_aspect
from brdfcorr.errors import InputError
from brdfcorr.testing import file_digests, georeference, synthetic_scene

#: A plane rising 1 m per 10 m pixel eastwards: slope atan(0.1) = 5.71 deg wherever it is defined.
PLANE = np.tile(np.arange(16, dtype=float), (16, 1))


def _nan_checkerboard() -> np.ndarray:
    """The plane with every other pixel NaN: each 3x3 neighbourhood holds a NaN, so no slope."""
    heights = PLANE.copy()
    heights[(np.add.outer(np.arange(16), np.arange(16)) % 2) == 1] = np.nan
    return heights


@pytest.mark.parametrize("heights", [np.full((16, 16), np.nan), _nan_checkerboard()],
                         ids=["nodata only", "isolated valid pixels"])
@pytest.mark.parametrize("lazy", [False, True], ids=["numpy", "dask"])
def test_no_slope_anywhere_is_an_input_error_naming_the_dem(heights, lazy):
    data = da.from_array(heights, chunks=8) if lazy else heights
    surface = slope_aspect(xr.DataArray(data, dims=("y", "x")), pixel_size=10.0)
    assert np.isnan(np.asarray(surface.slope)).all()  # what normalize would write as nodata everywhere
    with pytest.raises(InputError, match=r"^DEM file dem\.tif: no pixel has a slope"):
        check_dem_slope(surface, "DEM file dem.tif")


@pytest.mark.parametrize("lazy", [False, True], ids=["numpy", "dask"])
def test_one_pixel_with_a_slope_is_enough(lazy):
    heights = np.full((16, 16), np.nan)
    heights[5:8, 9:12] = PLANE[5:8, 9:12]  # one full 3x3 neighbourhood, around (6, 10)
    data = da.from_array(heights, chunks=8) if lazy else heights
    surface = slope_aspect(xr.DataArray(data, dims=("y", "x")), pixel_size=10.0)
    slope = np.asarray(surface.slope)
    assert np.isfinite(slope).sum() == 1
    np.testing.assert_allclose(slope[6, 10], np.degrees(np.arctan(0.1)))  # closed form of the plane
    check_dem_slope(surface, "DEM file dem.tif")  # no error


def test_correct_with_a_nodata_dem_exits_2_naming_it(tmp_path, write_example_scene):
    paths = write_example_scene(tmp_path / "scene", synthetic_scene(ny=32, nx=32))
    params = paths["params"]
    dem = georeference(xr.DataArray(np.full((1, 32, 32), -9999.0, dtype=np.float32), dims=("band", "y", "x")))
    dem_path = tmp_path / "scene" / "dem.tif"
    dem.rio.write_nodata(-9999.0).rio.to_raster(dem_path)
    before = file_digests(tmp_path / "scene")
    output = tmp_path / "out.tif"
    result = CliRunner().invoke(main, [str(a) for a in (
        "correct", paths["image"], "--angles", paths["angles"], "--classes", paths["classes"], "--params", params,
        "--dem", dem_path, "-o", output, "--qa", tmp_path / "qa.tif", "--no-progress")])
    assert result.exit_code == 2, result.output
    assert result.stderr.splitlines() == [
        f"brdfcorr: error: DEM file {dem_path}: no pixel has a slope: every 3x3 neighbourhood holds nodata, NaN or "
        "inf (a DEM of nodata only?); nothing could be corrected"]
    assert not output.exists() and not (tmp_path / "qa.tif").exists()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["scene"]  # no temporary file either
    assert file_digests(tmp_path / "scene") == before
