"""A time series of product folders as one cube (issue 38): :func:`brdfcorr.tasks.series.open_products`
gives, through the accessor, the NBAR that ``brdfcorr nbar`` writes for each folder alone."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import rasterio
from click.testing import CliRunner

import brdfcorr  # noqa: F401 (the .brdf accessor)
from brdfcorr.cli import main
from brdfcorr.errors import SensorInputError
from brdfcorr.tasks.series import open_products
from brdfcorr.testing import write_landsat_c2, write_sentinel2_safe

#: Three dates of one tile, each with its own time and sun (zenith range [deg]).
DATES = [("20240421T103000", (40.0, 42.0)), ("20240401T103000", (55.0, 57.0)), ("20240411T103000", (47.0, 49.0))]


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    directory = tmp_path_factory.mktemp("series")
    return [write_sentinel2_safe(directory, size=16, seed=0, sensed=sensed) for sensed in DATES]


def test_each_date_of_the_cube_is_the_nbar_of_its_folder(folders, tmp_path):
    series = open_products(folders)
    nbar, qa = series.reflectance.brdf.normalize(None, series.angles, series.table, reference={"sza": 45.0})
    assert nbar.dims == ("time", "band", "y", "x") and nbar.chunks is not None  # lazy
    assert list(series.reflectance["time"].values) == sorted(pd.Timestamp(when) for when, _ in DATES)
    for index, folder in enumerate(series.products):
        output = tmp_path / f"nbar{index}.tif"
        result = CliRunner().invoke(main, ["nbar", str(folder.path), "-o", str(output), "--ref-sza", "45",
                                           "--no-progress"])
        assert result.exit_code == 0, result.output
        with rasterio.open(output) as dataset:
            expected, names = dataset.read(), dataset.descriptions
        assert tuple(series.reflectance["band"].values) == names
        np.testing.assert_array_equal(nbar.isel(time=index).values, expected)
    # the SCL's cloud row (the first at 20 m) is no data on every date, the rest corrected
    assert np.isnan(nbar.isel(y=0)).all() and np.isfinite(nbar.isel(y=slice(1, None))).all()


def test_the_sun_of_each_date_is_its_own(folders):
    series = open_products(folders)
    suns = series.angles["sza"].mean(["y", "x"]).values
    assert np.all(np.diff(suns) < 0)  # April: the sun rises, dates sorted by time
    assert all(lo - 0.1 < s < hi + 0.1 for s, (lo, hi) in zip(suns, [(55, 57), (47, 49), (40, 42)]))


def test_folders_of_another_sensor_are_refused(folders, tmp_path):
    landsat = write_landsat_c2(tmp_path, size=16, angle_bands=True)
    # the Landsat scene (2011) comes first in time: the SAFE folder is the one named
    with pytest.raises(SensorInputError, match=r"\.SAFE: its sensor, bands, grid \(CRS, transform, size\) differ "
                                               rf"from those of {landsat}; a series is one sensor's bands on one grid"):
        open_products([folders[0], landsat])
    with pytest.raises(SensorInputError, match="no product folder given"):
        open_products([])


def test_the_example_writes_a_series_that_opens(tmp_path, monkeypatch):
    import runpy
    from pathlib import Path

    script = Path(__file__).parents[2] / "examples" / "sentinel2_series.py"
    monkeypatch.setattr("sys.argv", [str(script), str(tmp_path), "--dates", "3", "--size", "8"])
    runpy.run_path(str(script), run_name="__main__")
    series = open_products(sorted(tmp_path.glob("*.SAFE")))
    assert series.reflectance.sizes == {"time": 3, "band": 9, "y": 8, "x": 8}
    # the tile's sun zenith ranges start at 55, 42.5 and 30 deg (np.linspace(55, 30, 3)): one window
    # of the tile sees each date's grid at the same place, 12.5 deg apart
    suns = series.angles["sza"].mean(["y", "x"]).values
    np.testing.assert_allclose(np.diff(suns), [-12.5, -12.5], atol=1e-9)
