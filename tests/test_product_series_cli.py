"""Product folders as a time series from the command line (issue 37, part 3): ``brdfcorr
fit-classes SAFE1 SAFE2 ... --classes MAP`` fits the dates at once, each pixel's level free, and
``brdfcorr correct SAFE --params TABLE`` corrects one date; both give what the Python path gives
(:func:`brdfcorr.tasks.series.open_products` and the ``.brdf`` accessor), value for value."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import rasterio
import rioxarray

import brdfcorr  # noqa: F401  (the .brdf accessor)
from brdfcorr.errors import GridMismatchError, ParameterError
from brdfcorr.fit import ClassModels, GuardRails, Sampling
from brdfcorr.io.scene import SceneSources
from brdfcorr.params import ClassEntry, ParameterTable
from brdfcorr.tasks.correct import correct_files
from brdfcorr.tasks.fit import SceneFiles, fit_class_files
from brdfcorr.tasks.request import CorrectionRequest, OutputFiles
from brdfcorr.tasks.series import find_products, open_products, stacked_products
from brdfcorr.testing import SERIES_SHAPE, file_digests, write_sentinel2_series
from brdfcorr.testing.products import write_landsat_c2, write_stac_item

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
    # The table's provenance names the folders given, not the scratch rasters that stacked their bands.
    names = ", ".join(folder.name for folder in _folders(series))
    assert all(entry.fit.source.startswith(f"brdfcorr fit-classes {names} (") for entry in cli.classes)
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
    # An offset of 0 is given too (it was taken for not given: the product's -0.1 applied, exit 0).
    code, stderr = invoke(["correct", folders[0], "--offset", "0", "--params", "roy2017", "-o", tmp_path / "c.tif"])
    assert code == 2 and "--offset: product folders bring their own angles, scaling and wavelengths" in stderr
    assert not list(tmp_path.iterdir())


# ----------------------------------------------------------------- errors name what the user gave
# A product's bands reach the correction and the fit as a virtual raster stacked in a scratch folder
# (tasks.series.product_sources): an error about the image names the folder or STAC item given.


def _three_band_table(path: Path) -> Path:
    """A table of 3 per-band values: it fits no Sentinel-2 product's 9 bands at 20 m."""
    ParameterTable(classes=[ClassEntry(id=1, name="three", model="ross_thick_li_sparse", params={
        "f_iso": [0.1] * 3, "f_vol": [0.02] * 3, "f_geo": [0.01] * 3})]).save(path)
    return path


def _half_class_map(series: Path, target: Path) -> Path:
    """The series' class map cut to its upper-left quarter: not on the products' grid."""
    with rasterio.open(series / "tiles" / "classes.tif") as source:
        profile, values = source.profile, source.read(1)
    rows, columns = values.shape[0] // 2, values.shape[1] // 2
    profile.update(height=rows, width=columns)
    with rasterio.open(target, "w", **profile) as sink:
        sink.write(values[:rows, :columns], 1)
    return target


def _names_the_product(line: str, product: Path) -> None:
    assert f"{product} " in f"{line} ".replace(")", " ").replace(":", " ") and ".vrt" not in line, line
    assert "brdfcorr-products" not in line, line


def test_errors_of_correct_and_fit_classes_name_the_product_folder(series, invoke, tmp_path):
    folder, table = _folders(series)[0], _three_band_table(tmp_path / "three.yaml")
    half = _half_class_map(series, tmp_path / "half.tif")
    for args in (["correct", folder, "--params", table],  # the table does not fit the bands
                 ["correct", folder, "--params", table, "--factor-at", "nodes"],
                 ["correct", folder, "--params", "roy2017", "--classes", half],  # a class map on another grid
                 ["fit-classes", *_folders(series)[:2], "--classes", half]):
        target = tmp_path / ("out.yaml" if args[0] == "fit-classes" else "out.tif")
        code, stderr = invoke([*args, "-o", target, "--no-progress"])
        assert code == 2, stderr
        assert len(stderr.splitlines()) == 1 and stderr.startswith("brdfcorr: error: "), stderr
        _names_the_product(stderr.strip(), folder)
        assert not target.exists()


def test_errors_name_the_stac_item_and_the_folder_in_python(series, tmp_path):
    safe = shutil.copytree(_folders(series)[0], tmp_path / _folders(series)[0].name)
    item = write_stac_item(safe)
    table = ParameterTable.load(_three_band_table(tmp_path / "three.yaml"))
    for product in (item, safe):
        with stacked_products(find_products([product])) as [found]:
            request = CorrectionRequest(SceneSources(classes=None, **found), table,
                                        OutputFiles(tmp_path / "out.tif"))
            with pytest.raises(ParameterError) as raised:
                correct_files(request)
        _names_the_product(str(raised.value), product)
    half = _half_class_map(series, tmp_path / "half.tif")
    with stacked_products(find_products([safe])) as [found], pytest.raises(GridMismatchError) as raised:
        fit_class_files([SceneFiles(classes=half, **found)], ClassModels("ross_thick_li_sparse"))
    _names_the_product(str(raised.value), safe)
    assert not (tmp_path / "out.tif").exists()


# ------------------------------------------------- the output guard: a product's files are inputs


@pytest.mark.parametrize("option", ["-o", "--report"])
@pytest.mark.parametrize("overwrite", [False, True])
def test_fit_classes_refuses_an_output_that_is_a_band_file_of_a_product(series, invoke, tmp_path, option,
                                                                        overwrite):
    folders = _folders(series)[:2]
    band = next(folders[1].glob("GRANULE/*/IMG_DATA/R20m/*_B04_20m.jp2"))
    outputs = {"-o": tmp_path / "t.yaml", option: band}
    before = file_digests(series / "tiles")
    code, stderr = invoke(["fit-classes", *folders, "--classes", series / "tiles" / "classes.tif",
                           *(item for pair in outputs.items() for item in pair),
                           *(["--overwrite"] if overwrite else []), "--no-progress"])
    assert code == 2, stderr
    assert len(stderr.splitlines()) == 1, stderr
    assert f"{option} {band} is also an input" in stderr and f"band B04 of {folders[1].name}" in stderr, stderr
    assert file_digests(series / "tiles") == before
    assert not list(tmp_path.iterdir())


def test_fit_classes_and_correct_refuse_to_write_over_a_landsat_band(invoke, tmp_path):
    folder = write_landsat_c2(tmp_path / "landsat", angle_bands=True)
    band = next(folder.glob("*_SR_B4.TIF"))
    before = file_digests(folder)
    for args, named in ((["fit-classes", folder, "--classes", tmp_path / "classes.tif"], "-o"),
                        (["correct", folder, "--params", "roy2017"], "output")):
        code, stderr = invoke([*args, "-o", band, "--overwrite", "--no-progress"])
        assert code == 2, stderr
        assert len(stderr.splitlines()) == 1 and f"{named} {band} is also an input" in stderr, stderr
        assert f"band SR_B4 of {folder.name}" in stderr, stderr
    assert file_digests(folder) == before


# ------------------------------------------------------- a product is identified once per run (issue 42)


def test_correct_and_fit_classes_identify_each_product_once(series, table, invoke, identified, tmp_path):
    """The output guard (the product's files are inputs) and the stack of the bands use the product
    found once: one identification per folder and command."""
    folders = _folders(series)
    code, stderr = invoke(["correct", folders[0], "--classes", series / "tiles" / "classes.tif", "--params", table,
                           "--ref-sza", "45", "-o", tmp_path / "date.tif", "--no-progress"])
    assert code == 0, stderr
    assert identified == {folders[0].name: 1}
    identified.clear()
    code, stderr = invoke(["fit-classes", *folders, "--classes", series / "tiles" / "classes.tif",
                           "--model", "ross_thick_li_sparse", *FIT, "-o", tmp_path / "t.yaml", "--no-progress"])
    assert code == 0, stderr
    assert identified == {folder.name: 1 for folder in folders} and len(folders) == 4
