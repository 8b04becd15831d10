"""Class maps from the CLI: NDVI strata of an image, land-cover maps on another grid (opt-in), code
lookup tables; the correction with an aligned or remapped map equals the one with the native map."""

from __future__ import annotations

import numpy as np
import pytest
import rasterio
import rioxarray
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.testing import synthetic_scene


@pytest.fixture(scope="module")
def files(tmp_path_factory, write_example_scene):
    return write_example_scene(tmp_path_factory.mktemp("classmaps"), synthetic_scene(ny=32, nx=48))


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _correct(files, output, classes, *extra):
    result = _invoke("correct", files["image"], "--angles", files["angles"], "--classes", classes,
                     "--params", files["params"], "--ref-sza", "35", "-o", output, *extra)
    assert result.exit_code == 0, result.output
    return rioxarray.open_rasterio(output).values


def test_finer_class_map_in_the_same_crs_is_refused_unless_aligned(files, tmp_path):
    # Each 10 m pixel of the image holds 2 x 2 pixels of a 5 m map with the same class: nearest
    # neighbour onto the image grid must give back the native map exactly.
    native = rioxarray.open_rasterio(files["classes"]).squeeze("band", drop=True)
    fine = native.rio.reproject(native.rio.crs, resolution=5.0, resampling=rasterio.enums.Resampling.nearest)
    np.testing.assert_array_equal(fine.values[::2, ::2], native.values)
    fine.rio.to_raster(tmp_path / "fine.tif")

    refused = _invoke("correct", files["image"], "--angles", files["angles"], "--classes", tmp_path / "fine.tif",
                      "--params", files["params"], "-o", tmp_path / "refused.tif")
    assert refused.exit_code == 2 and "is not on the grid of" in refused.output

    expected = _correct(files, tmp_path / "native.tif", files["classes"])
    aligned = _correct(files, tmp_path / "aligned.tif", tmp_path / "fine.tif", "--align-classes")
    np.testing.assert_array_equal(aligned, expected)
    with rasterio.open(tmp_path / "aligned.tif") as dataset:
        assert dataset.tags()["brdf_class_map"].startswith("resampled from EPSG:32632 (5 x 5 metre, nearest)")


def test_lookup_table_maps_land_cover_codes_to_table_ids(files, tmp_path):
    native = rioxarray.open_rasterio(files["classes"])
    codes = native.copy(data=np.where(native.values == 255, 255, native.values * 10).astype(np.uint8))
    codes.rio.to_raster(tmp_path / "codes.tif")
    (tmp_path / "lookup.yaml").write_text("10: 1\n20: 2\n30: 3\n40: 4\n")
    expected = _correct(files, tmp_path / "native.tif", files["classes"])
    remapped = _correct(files, tmp_path / "remapped.tif", tmp_path / "codes.tif", "--class-lookup",
                        tmp_path / "lookup.yaml")
    np.testing.assert_array_equal(remapped, expected)


def test_bad_lookup_table_is_one_error_line(files, tmp_path):
    (tmp_path / "lookup.yaml").write_text("ten: 1\n")
    result = _invoke("correct", files["image"], "--angles", files["angles"], "--classes", files["classes"],
                     "--params", files["params"], "--class-lookup", tmp_path / "lookup.yaml", "-o", tmp_path / "x.tif")
    assert result.exit_code == 2
    assert result.stderr.splitlines() == [
        f"brdfcorr: error: lookup table {tmp_path / 'lookup.yaml'}: 'ten': 1 is not an integer code and a class id "
        "in 0..65535"]
    assert not (tmp_path / "x.tif").exists()


def test_classes_ndvi_writes_the_strata_of_the_image(files, tmp_path):
    result = _invoke("classes", "ndvi", files["image"], "--edges", "0.2,0.5", "-o", tmp_path / "strata.tif")
    assert result.exit_code == 0, result.output
    image = rioxarray.open_rasterio(files["image"]).values.astype(float)
    red, nir = image[2], image[3]  # 660 and 830 nm: the bands in the default red and NIR ranges
    ndvi = (nir - red) / (nir + red)
    expected = np.digitize(ndvi, [0.2, 0.5]) + 1  # left-closed bins 1..3
    with rasterio.open(tmp_path / "strata.tif") as dataset:
        classes, tags = dataset.read(1), dataset.tags()
    water_or_shadow = classes == 0  # masked pixels: no class
    np.testing.assert_array_equal(classes[~water_or_shadow], expected[~water_or_shadow])
    assert "NDVI strata of image.tif; edges 0.2,0.5" == tags["brdf_class_map"]
    assert "ndvi_0.20_0.50" in result.output


def test_classes_align_writes_the_map_on_the_image_grid(files, tmp_path):
    native = rioxarray.open_rasterio(files["classes"]).squeeze("band", drop=True)
    coarse = native.rio.reproject(native.rio.crs, resolution=20.0, resampling=rasterio.enums.Resampling.nearest)
    coarse.rio.to_raster(tmp_path / "coarse.tif")
    result = _invoke("classes", "align", tmp_path / "coarse.tif", "--like", files["image"],
                     "-o", tmp_path / "on_grid.tif")
    assert result.exit_code == 0, result.output
    on_grid = rioxarray.open_rasterio(tmp_path / "on_grid.tif").squeeze("band", drop=True)
    image = rioxarray.open_rasterio(files["image"])
    assert on_grid.shape == image.shape[1:] and on_grid.rio.transform() == image.rio.transform()
    # Every 10 m pixel takes the class of the 20 m cell containing its centre.
    np.testing.assert_array_equal(on_grid.values, np.repeat(np.repeat(coarse.values, 2, 0), 2, 1)[:32, :48])
