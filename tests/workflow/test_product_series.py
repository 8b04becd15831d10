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
        # nbar samples the per-pixel factor (correction.subgrid: within 1e-4 of it), normalize evaluates it everywhere
        np.testing.assert_allclose(nbar.isel(time=index).values, expected, rtol=1e-4)
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


@pytest.mark.parametrize("kind", ["sentinel2", "landsat"])
def test_the_table_follows_the_cubes_bands_not_their_positions(folders, tmp_path, kind):
    """The c-factor corrects each band on its own, so a cube of the series' bands in another order,
    or some of them, must give each band the values it has in the whole cube. The series' table
    was applied by position: the reversed cube took the weights of the band at the mirrored place,
    about 1 % off (a bug hunt). It now carries the bands' centres [nm] and is matched to the cube's
    ``wavelength`` coordinate; Landsat's SR_B* names alone give none, so a cube without the
    coordinate is refused rather than corrected by position."""
    from brdfcorr.errors import ParameterError

    products = folders[:1] if kind == "sentinel2" else [write_landsat_c2(tmp_path, size=8, angle_bands=True)]
    series = open_products(products)
    reference = {"sza": 45.0}
    whole, _ = series.reflectance.brdf.normalize(None, series.angles, series.table, reference=reference)
    for picked in (slice(None, None, -1), [2, 0]):
        cube = series.reflectance.isel(band=picked)
        part, _ = cube.brdf.normalize(None, series.angles, series.table, reference=reference)
        expected = whole.sel(band=cube["band"].values)
        np.testing.assert_allclose(part.values, expected.values, rtol=1e-6, equal_nan=True)
    assert series.table[1].wavelengths == sorted(series.products[0].wavelengths)  # the bands' centres [nm]
    if kind == "landsat":
        with pytest.raises(ParameterError, match=r"the image's band wavelengths are needed \(a 'wavelength' coordinate"):
            series.reflectance.drop_vars("wavelength").brdf.normalize(None, series.angles, series.table,
                                                                     reference=reference)


# --- STAC items with local assets ---------------------------------------------------------------

@pytest.mark.parametrize("layout", ["earth_search", "planetary_computer"])
def test_stac_items_read_as_their_safe_folders(folders, tmp_path, layout):
    """An item written from each SAFE folder gives the same cube and angles, and `brdfcorr nbar
    item.json` the same file as `brdfcorr nbar FOLDER`: in Earth Search v1's layout (assets keyed
    and their eo:bands named by common name, red, nir08, each beside a remote JPEG 2000 copy of the
    same name; refused as "no asset for B02, ..." before, a bug hunt) and the Planetary Computer's
    (B04)."""
    from brdfcorr.testing import write_stac_item

    items = [write_stac_item(folder, layout=layout) for folder in folders]
    by_folder, by_item = open_products(folders), open_products(items)
    np.testing.assert_array_equal(by_item.reflectance.values, by_folder.reflectance.values)
    for name in ("sza", "saa", "vza", "vaa"):
        np.testing.assert_array_equal(by_item.angles[name].values, by_folder.angles[name].values)
    outputs = []
    for source in (folders[0], items[0]):
        output = tmp_path / f"{source.suffix.lstrip('.')}.tif"
        result = CliRunner().invoke(main, ["nbar", str(source), "-o", str(output), "--no-progress"])
        assert result.exit_code == 0, result.output
        with rasterio.open(output) as dataset:
            outputs.append(dataset.read())
    np.testing.assert_array_equal(*outputs)


def test_the_earth_search_nir_bands_are_b08_and_b8a(folders):
    """Earth Search v1 keys B08 as ``nir`` and B8A as ``nir08`` (the real item
    S2A_39QTA_20230628_0_L2A: nir is B08.tif, nir08 B8A.tif): at 10 m both, as the folder reads them."""
    from brdfcorr.testing import write_stac_item

    by_folder = open_products(folders[:1], resolution=10, bands=["B08", "B8A"])
    by_item = open_products([write_stac_item(folders[0])], resolution=10, bands=["B08", "B8A"])
    assert [file.name[-11:] for file in by_item.products[0].bands.values()] == ["B08_10m.jp2", "B8A_20m.jp2"]
    np.testing.assert_array_equal(by_item.reflectance.values, by_folder.reflectance.values)


def test_an_item_without_raster_scaling_takes_esas_of_its_baseline(folders):
    from brdfcorr.testing import write_stac_item

    scaled = open_products([write_stac_item(folders[0])])
    unscaled = open_products([write_stac_item(folders[0], scaling=False)])  # 04.00: 1/10000 and -0.1
    np.testing.assert_array_equal(unscaled.reflectance.values, scaled.reflectance.values)
    assert "no raster:bands scaling: ESA's of processing baseline 04.00" in unscaled.products[0].notes


@pytest.mark.parametrize("flag", ["earthsearch:boa_offset_applied", "sentinel:boa_offset_applied"])
def test_an_item_whose_files_hold_the_offset_already_is_not_offset_again(folders, flag):
    """Earth Search flags items whose COGs hold DN - 1000 already while raster:bands still say -0.1
    (Element84/earth-search issue 66): read with -0.1, each value was 0.1 too low, without a word.
    Read with offset 0 (the same files unflagged: DN x 0.0001 - 0.1, so 0.1 above them)."""
    import json

    from brdfcorr.testing import write_stac_item

    path = write_stac_item(folders[0])
    plain = open_products([path])
    item = json.loads(path.read_text())
    readings = {}
    for value in (True, False):
        item["properties"][flag] = value
        flagged = path.with_name(f"{path.stem}_{value}.json")  # beside the item: its hrefs are relative
        flagged.write_text(json.dumps(item))
        try:
            readings[value] = open_products([flagged])
        finally:
            flagged.unlink()
    np.testing.assert_allclose(readings[True].reflectance.values, plain.reflectance.values + 0.1, atol=2e-7)
    assert any("boa_offset_applied" in note for note in readings[True].products[0].notes)
    np.testing.assert_array_equal(readings[False].reflectance.values, plain.reflectance.values)


@pytest.mark.parametrize("edit, message", [
    (lambda item: item["assets"]["red"].update(href="https://example.com/B04.tif"),
     r"asset red is remote \(https://example.com/B04.tif\); download the assets beside the item first"),
    (lambda item: item["assets"].pop("scl"), r"the item has no asset for SCL"),
    (lambda item: item["assets"].pop("granule_metadata"), r"the item has no asset for granule metadata"),
    (lambda item: item["properties"].update(platform="landsat-8", constellation=""),
     r"a STAC item of landsat-8; brdfcorr reads Sentinel-2 L2A items"),
    (lambda item: item["assets"]["red"]["raster:bands"][0].update(offset=-1000),
     r"asset red: scale 0.0001 and offset -1000 are no Sentinel-2 L2A scaling"),
    (lambda item: item.update(type="FeatureCollection"), r"not a STAC item"),
])
def test_a_stac_item_brdfcorr_cannot_read_is_one_line(folders, edit, message):
    import json

    from brdfcorr.testing import write_stac_item

    path = write_stac_item(folders[0])
    item = json.loads(path.read_text())
    edit(item)
    path.write_text(json.dumps(item))
    with pytest.raises(SensorInputError, match=message):
        open_products([path])
