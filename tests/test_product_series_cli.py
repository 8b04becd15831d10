"""Product folders as a time series from the command line (issue 37, part 3): ``brdfcorr
fit-classes SAFE1 SAFE2 ... --classes MAP`` fits the dates at once, each pixel's level free, and
``brdfcorr correct SAFE --params TABLE`` corrects one date; both give what the Python path gives
(:func:`brdfcorr.tasks.series.open_products` and the ``.brdf`` accessor), value for value."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rioxarray

import brdfcorr  # noqa: F401  (the .brdf accessor)
from brdfcorr.fit import GuardRails, Sampling
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.series import open_products
from brdfcorr.testing import SERIES_SHAPE, write_sentinel2_series

FIT = ["--levels", "pixel", "--block-size", "8", "--min-samples", "50"]


@pytest.fixture(scope="module")
def series(tmp_path_factory) -> Path:
    """Four dates of one synthetic tile whose 20 m bands carry a known RTLSR shape, and their class map."""
    root = tmp_path_factory.mktemp("products")
    write_sentinel2_series(root / "tiles", dates=4)
    return root


@pytest.fixture(scope="module")
def table(series, invoke) -> Path:
    """The table ``brdfcorr fit-classes`` fits over the four folders."""
    path = series / "table.yaml"
    code, stderr = invoke(["fit-classes", *_folders(series), "--classes", series / "tiles" / "classes.tif",
                           "--model", "ross_thick_li_sparse", *FIT, "-o", path])
    assert code == 0, stderr
    return path


def _folders(series: Path) -> list[Path]:
    return sorted((series / "tiles").glob("*.SAFE"))


def _python_path(series: Path):
    """The fit of the accessor over open_products' cube, with the options of FIT."""
    cube = open_products(_folders(series))
    classes = rioxarray.open_rasterio(series / "tiles" / "classes.tif").squeeze("band", drop=True)
    fitted = cube.reflectance.brdf.fit_classes(classes, cube.angles, "ross_thick_li_sparse",
                                               sampling=Sampling(block_size=8, levels="pixel"),
                                               guard=GuardRails(min_samples=50))
    return cube, classes, fitted


def test_fit_classes_over_product_folders_is_the_accessors_fit(series, table):
    _, _, fitted = _python_path(series)
    cli = ParameterTable.load(table)
    assert [entry.id for entry in cli.classes] == [entry.id for entry in fitted.table.classes] == [1, 2]
    for ours, theirs in zip(cli.classes, fitted.table.classes):
        assert ours.model == theirs.model
        for name in ("f_iso", "f_vol", "f_geo"):  # value for value
            np.testing.assert_array_equal(np.asarray(ours.params[name]), np.asarray(theirs.params[name]))
    for fit in fitted.fits:  # and a fit of the shape the dates were written with (known: SERIES_SHAPE)
        assert fit.levels == "pixel"
        ratios = np.asarray(fit.params["f_vol"]) / np.asarray(fit.params["f_iso"])
        np.testing.assert_allclose(ratios, SERIES_SHAPE[0], atol=0.03)


def test_correct_of_one_product_folder_is_the_accessors_date(series, table, invoke):
    cube, classes, _ = _python_path(series)
    corrected, _ = cube.reflectance.brdf.normalize(classes, cube.angles, ParameterTable.load(table),
                                                   reference={"sza": 45.0})
    dates = {}
    for date in (0, 3):  # the first and the last date
        output = series / f"date{date}.tif"
        code, stderr = invoke(["correct", _folders(series)[date], "--classes", series / "tiles" / "classes.tif",
                               "--params", table, "--ref-sza", "45", "-o", output, "--no-progress"])
        assert code == 0, stderr
        dates[date] = rioxarray.open_rasterio(output, masked=True).values
        np.testing.assert_array_equal(dates[date], corrected.isel(time=date).values.astype(np.float32))
    # The dates are one ground under a sun 25 deg apart: the correction to one sun brings them together.
    raw = cube.reflectance.isel(time=[0, 3]).values
    ok = np.isfinite(dates[0]) & np.isfinite(dates[3])
    assert ok.mean() > 0.9
    assert np.median(np.abs(raw[0] / raw[1] - 1)[ok]) > 0.05
    assert np.median(np.abs(dates[0] / dates[3] - 1)[ok]) < 0.01


def test_product_folders_refuse_angles_and_a_mix_with_files(series, invoke, tmp_path):
    folders = _folders(series)
    code, stderr = invoke(["fit-classes", *folders[:2], "--classes", series / "tiles" / "classes.tif",
                           "--angles", "x.tif", "--angles", "y.tif", "-o", tmp_path / "t.yaml"])
    assert code == 2 and "bring their own angles" in stderr
    code, stderr = invoke(["fit-classes", folders[0], series / "tiles" / "classes.tif", "--classes",
                           series / "tiles" / "classes.tif", "-o", tmp_path / "t.yaml"])
    assert code == 2 and "not both" in stderr
    code, stderr = invoke(["correct", folders[0], "--angles", "x.tif", "--params", "roy2017",
                           "-o", tmp_path / "c.tif"])
    assert code == 2 and "--angles: product folders bring their own angles, scaling and wavelengths; leave it out" in stderr
    assert not list(tmp_path.iterdir())
