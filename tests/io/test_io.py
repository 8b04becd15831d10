"""Tests of brdfcorr.io.rasters: readers, wavelengths, grid checks, atomic chunked GeoTIFF writes."""

from __future__ import annotations

from pathlib import Path

import dask.array as da
import numpy as np
import pytest
import rasterio
import xarray as xr

from brdfcorr import io
from brdfcorr.errors import GridMismatchError, InputError
from brdfcorr.testing import georeference, synthetic_scene, write_scene


@pytest.fixture(scope="module")
def scene():
    return synthetic_scene(ny=40, nx=48)


@pytest.fixture(scope="module")
def files(scene, tmp_path_factory):
    return write_scene(tmp_path_factory.mktemp("scene"), scene)


def _write(path: Path, data: np.ndarray, **profile) -> Path:
    base = {"driver": "GTiff", "height": data.shape[1], "width": data.shape[2], "count": data.shape[0],
            "dtype": data.dtype.name, "crs": "EPSG:32632",
            "transform": rasterio.transform.from_origin(500000, 5400000, 10, 10)}
    base.update(profile)
    with rasterio.open(path, "w", **base) as dataset:
        dataset.write(data)
    return path


@pytest.mark.parametrize("text, expected", [
    ("560", 560.0), ("560 nm", 560.0), ("560.5nm", 560.5), ("0.56 um", 560.0), ("0.865 µm", 865.0),
    ("B3 (560 nm)", 560.0), ("1.6 micrometers", 1600.0),
    ("Band 3", None), ("", None), ("red", None), ("560 furlongs", None),
    # A range is the band's extent: its middle is the centre (its upper end was taken before).
    ("Blue 460-500 nm", 480.0), ("Band 1 (0.455-0.505 µm)", 480.0), ("NIR 805 nm - 855 nm", 830.0),
    ("0.455 to 0.505 um", 480.0),
    # Two wavelengths and no word for which is the centre: none (10 nm was taken before).
    ("FWHM 10 nm, centre 480 nm", None),
])
def test_parse_wavelength(text, expected):
    result = io.parse_wavelength(text)
    assert result == pytest.approx(expected) if expected is not None else result is None


def test_image_wavelengths_from_band_descriptions(files, scene):
    image = io.open_image(files["image"])
    np.testing.assert_array_equal(image["wavelength"], scene["reflectance"]["wavelength"])
    assert image["wavelength"].attrs["units"] == "nm"
    assert isinstance(image.data, da.Array)
    np.testing.assert_array_equal(image.values, scene["reflectance"].values)  # float32 round trip


def test_wavelength_tag_takes_precedence_over_descriptions(tmp_path):
    path = _write(tmp_path / "tagged.tif", np.zeros((3, 4, 4), "float32"))
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(wavelength="0.45, 0.55,0.65", wavelength_units="um")
        dataset.descriptions = ("1 nm", "2 nm", "3 nm")
    image = io.open_image(path)
    np.testing.assert_allclose(image["wavelength"], [450, 550, 650])
    explicit = io.open_image(path, wavelengths=[400, 500, 600])
    np.testing.assert_allclose(explicit["wavelength"], [400, 500, 600])
    with pytest.raises(InputError, match="2 wavelengths from the given wavelengths for 3 bands"):
        io.open_image(path, wavelengths=[400, 500])


def test_no_wavelengths_means_no_coordinate(tmp_path):
    path = _write(tmp_path / "plain.tif", np.zeros((2, 4, 4), "float32"))
    with rasterio.open(path, "r+") as dataset:
        dataset.descriptions = ("Band 1", "Band 2")
    assert "wavelength" not in io.open_image(path).coords


def test_bad_wavelength_tag(tmp_path):
    path = _write(tmp_path / "bad.tif", np.zeros((2, 4, 4), "float32"))
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(wavelength="blue,green")
    with pytest.raises(InputError, match="bad.tif: tag wavelength='blue,green'"):
        io.open_image(path)


def test_angles_from_one_file_or_four(files, scene, tmp_path):
    stacked = io.open_angles(files["angles"])
    separate = {}
    for name in io.ANGLE_NAMES:
        separate[name] = tmp_path / f"{name}.tif"
        scene[name].rio.to_raster(separate[name])
    four = io.open_angles(**separate)
    for name in io.ANGLE_NAMES:
        np.testing.assert_array_equal(stacked[name].values, scene[name].values)
        np.testing.assert_array_equal(four[name].values, scene[name].values)
        assert stacked[name].dims == ("y", "x")
    with pytest.raises(InputError, match="missing angle file.*vaa"):
        io.open_angles(sza=separate["sza"], saa=separate["saa"], vza=separate["vza"])
    with pytest.raises(InputError, match="not both"):
        io.open_angles(files["angles"], sza=separate["sza"])
    with pytest.raises(InputError, match="has 4 bands; it needs 1"):
        io.open_angles(sza=files["angles"], saa=separate["saa"], vza=separate["vza"], vaa=separate["vaa"])
    with pytest.raises(InputError, match=r"angle file .*classes.tif has 1 bands; it needs 4"):
        io.open_angles(files["classes"])


def test_classes_keep_integers_and_nodata(files, scene):
    classes = io.open_classes(files["classes"])
    assert classes.dtype == np.uint8 and classes.rio.nodata == 255
    np.testing.assert_array_equal(classes.values, scene["classes"].values)
    with pytest.raises(InputError, match="class map .*image.tif has 4 bands"):
        io.open_classes(files["image"])


def test_missing_file_is_named(tmp_path):
    with pytest.raises(InputError, match=r"image file .*nothing.tif does not exist"):
        io.open_image(tmp_path / "nothing.tif")
    (tmp_path / "junk.tif").write_text("not a raster")
    with pytest.raises(InputError, match="cannot read image file .*junk.tif"):
        io.open_image(tmp_path / "junk.tif")


def test_same_grid_passes(files):
    io.check_same_grid({"image": io.open_image(files["image"]), "classes": io.open_classes(files["classes"]),
                        **io.open_angles(files["angles"])})


@pytest.mark.parametrize("change, pattern", [
    ({"height": 39}, r"shape \(rows, columns\) \(39, 48\) differs from \(40, 48\)"),
    ({"crs": "EPSG:32633"}, r"CRS EPSG:32633 differs from EPSG:32632"),
    ({"transform": rasterio.transform.from_origin(500010, 5400000, 10, 10)}, r"transform .* differs from"),
    ({"transform": rasterio.transform.from_origin(500000, 5400000, 20, 20)}, r"transform .* differs from"),
])
def test_grid_mismatch_says_which_layer_and_what(files, tmp_path, change, pattern):
    height = change.get("height", 40)
    path = _write(tmp_path / "classes_other.tif", np.ones((1, height, 48), "uint8"), **change)
    layers = {"image": io.open_image(files["image"]), "classes": io.open_classes(path)}
    with pytest.raises(GridMismatchError, match=rf"classes \(.*classes_other.tif\) is not on the grid of "
                                                 rf"image \(.*image.tif\): {pattern}"):
        io.check_same_grid(layers)


def test_write_round_trip_georeference_tags_descriptions(files, tmp_path):
    image = io.open_image(files["image"], chunks=16)
    out = image.drop_vars("wavelength").rio.write_nodata(np.nan, encoded=True)
    target = tmp_path / "out.tif"
    io.write_rasters({target: out}, tags={"brdf_reference": "sza=30 vza=0 raa=0"}, geotiff=io.GeoTiffOutput(blocksize=16))
    with rasterio.open(target) as written, rasterio.open(files["image"]) as source:
        assert written.crs == source.crs
        assert written.transform == source.transform
        assert np.isnan(written.nodata)
        assert written.descriptions == ("480 nm", "560 nm", "660 nm", "830 nm")
        assert written.tags()["brdf_reference"] == "sza=30 vza=0 raa=0"
        assert written.profile["tiled"] and written.block_shapes[0] == (16, 16)
        assert written.compression.value == "DEFLATE"
        np.testing.assert_array_equal(written.read(), source.read())
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.tif"]


def test_write_cog(files, tmp_path):
    image = io.open_image(files["image"], chunks=16)
    target = tmp_path / "out_cog.tif"
    io.write_rasters({target: image.drop_vars("wavelength")}, geotiff=io.GeoTiffOutput(cog=True, blocksize=16))
    with rasterio.open(target) as written:
        assert written.tags(ns="IMAGE_STRUCTURE").get("LAYOUT") == "COG"
        assert written.descriptions == ("480 nm", "560 nm", "660 nm", "830 nm")
        np.testing.assert_array_equal(written.read(), image.values)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out_cog.tif"]


def test_cog_overviews_keep_the_qa_flags_and_average_the_values(files, tmp_path):
    # The QA layer's overviews averaged its bit flags: a block [2, 2, 4, 4] (no_class, unknown
    # class) became 3 (nodata | no_class), a combination found nowhere at full resolution.
    from brdfcorr.correction.qa import qa_attrs

    image = io.open_image(files["image"], chunks=16).drop_vars("wavelength")
    rows, cols = image.shape[1:]
    flags = np.where(np.arange(rows)[:, None] % 2 == 0, 2, 4) * np.ones((1, cols), int)  # blocks [2, 2, 4, 4]
    qa = xr.DataArray(flags.astype(np.uint8), dims=("y", "x"), coords={"y": image.y, "x": image.x},
                      attrs=qa_attrs("BRDF normalization quality flags"))
    qa = qa.rio.write_crs(image.rio.crs).rio.write_transform(image.rio.transform())
    targets = {tmp_path / "qa.tif": qa, tmp_path / "out.tif": image}
    io.write_rasters(targets, geotiff=io.GeoTiffOutput(cog=True, blocksize=16))
    with rasterio.open(tmp_path / "qa.tif") as written:
        assert written.overviews(1), "no overview to check"
        overview = written.read(1, out_shape=(rows // 2, cols // 2))
    assert set(np.unique(overview)) <= {2, 4}
    with rasterio.open(tmp_path / "out.tif") as written:
        mean = image.values[0].reshape(rows // 2, 2, cols // 2, 2).mean(axis=(1, 3))
        np.testing.assert_allclose(written.read(1, out_shape=(rows // 2, cols // 2)), mean, rtol=1e-5)


def _failing_array(scene) -> xr.DataArray:
    def explode(block, block_info=None):
        if block_info[0]["chunk-location"] == (0, 1, 1):
            raise RuntimeError("disk on fire")
        return block

    data = da.from_array(scene["reflectance"].values, chunks=(4, 16, 16)).map_blocks(explode, dtype="float32")
    return scene["reflectance"].drop_vars("wavelength").copy(data=data)


@pytest.mark.parametrize("cog", [False, True])
def test_failed_write_leaves_nothing_at_the_target(scene, tmp_path, cog):
    target = tmp_path / "out.tif"
    qa_target = tmp_path / "qa.tif"
    qa = georeference(xr.DataArray(np.zeros((40, 48), "uint8"), dims=("y", "x")))
    with pytest.raises(RuntimeError, match="disk on fire"):
        io.write_rasters({target: _failing_array(scene), qa_target: qa}, geotiff=io.GeoTiffOutput(blocksize=16, cog=cog))
    assert list(tmp_path.iterdir()) == []


def test_existing_target_survives_a_failed_write(scene, tmp_path):
    target = tmp_path / "out.tif"
    target.write_bytes(b"previous result")
    with pytest.raises(RuntimeError):
        io.write_rasters({target: _failing_array(scene)}, geotiff=io.GeoTiffOutput(blocksize=16))
    assert target.read_bytes() == b"previous result"
    assert [p.name for p in tmp_path.iterdir()] == ["out.tif"]


def test_blocksize_must_be_a_multiple_of_16(scene, tmp_path):
    with pytest.raises(InputError, match="multiple of 16"):
        io.write_rasters({tmp_path / "x.tif": scene["reflectance"]}, geotiff=io.GeoTiffOutput(blocksize=20))


def test_envi_header_wavelengths(tmp_path):
    # GDAL's ENVI driver: "wavelength" and "wavelength units" header items (micrometres here).
    profile = {"driver": "ENVI", "height": 4, "width": 5, "count": 3, "dtype": "float32", "crs": "EPSG:32632",
               "transform": rasterio.transform.from_origin(500000, 5400000, 10, 10)}
    with rasterio.open(tmp_path / "cube.img", "w", **profile) as dataset:
        dataset.write(np.ones((3, 4, 5), "float32"))
    with open(tmp_path / "cube.hdr", "a") as header:
        header.write("wavelength units = Micrometers\nwavelength = { 0.45, 0.55, 0.65 }\n")
    np.testing.assert_allclose(io.open_image(tmp_path / "cube.img")["wavelength"], [450, 550, 650])


def test_a_band_tag_is_not_a_dataset_tag(tmp_path):
    path = _write(tmp_path / "bandtag.tif", np.zeros((3, 4, 4), "float32"))
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(1, wavelength="999")  # band 1 only: not the dataset's wavelength list
        dataset.descriptions = ("450 nm", "550 nm", "650 nm")
    np.testing.assert_allclose(io.open_image(path)["wavelength"], [450, 550, 650])


def _open_masked(path):
    """The image as rioxarray's masked, scaled read gives it (what open_image did for every file)."""
    from brdfcorr.io import rasters

    original = rasters._read_as_stored
    rasters._read_as_stored = lambda path: False
    try:
        return rasters.open_image(path, chunks=16)
    finally:
        rasters._read_as_stored = original


@pytest.mark.parametrize("nodata", [float("nan"), None])
def test_a_float_image_read_as_stored_equals_the_masked_read(tmp_path, nodata):
    # Float bands with NaN nodata (or none), no mask band, no scale: the unmasked read (issue 28,
    # a fifth less read time) gives the same values, attrs and nodata as the masked read.
    from brdfcorr.io import rasters

    data = np.random.default_rng(1).uniform(0, 0.6, (3, 40, 48)).astype("float32")
    data[:, :5, :7] = np.nan
    path = _write(tmp_path / "image.tif", data, nodata=nodata)
    plain, masked = rasters.open_image(path, chunks=16), _open_masked(path)
    assert rasters._read_as_stored(path) and rasters.identify_image(path).plain
    np.testing.assert_array_equal(plain.values, masked.values)
    identified = rasters.open_image(rasters.identify_image(path), chunks=16)  # carried: the same read
    np.testing.assert_array_equal(identified.values, plain.values)
    assert identified.attrs == plain.attrs and identified.encoding["source"] == plain.encoding["source"]
    assert plain.attrs == masked.attrs and plain.dtype == masked.dtype
    assert str(plain.rio.encoded_nodata) == str(masked.rio.encoded_nodata)


@pytest.mark.parametrize("kind", ["nodata", "mask band", "scale"])
def test_an_image_needing_the_masked_read_keeps_it(tmp_path, kind):
    # A numeric nodata, GDAL's mask band (masked pixels hold ordinary values) or a scale tag:
    # only the masked, scaled read gives reflectance factors with NaN where nothing was measured.
    from brdfcorr.io import rasters

    data = np.full((2, 32, 32), 0.25, "float32")
    if kind != "scale":  # (an undeclared -9999 beside a scale is refused: test_bad_input.py)
        data[:, :4, :4] = -9999.0
    path = _write(tmp_path / "image.tif", data, nodata=-9999.0 if kind == "nodata" else None)
    with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=True), rasterio.open(path, "r+") as dataset:
        if kind == "mask band":
            mask = np.full((32, 32), 255, "uint8")
            mask[:4, :4] = 0
            dataset.write_mask(mask)
        if kind == "scale":
            dataset.scales, dataset.offsets = (2.0, 2.0), (0.0, 0.0)
    assert not rasters._read_as_stored(path) and not rasters.identify_image(path).plain
    image = rasters.open_image(path, chunks=16).values
    np.testing.assert_array_equal(rasters.open_image(rasters.identify_image(path), chunks=16).values, image)
    if kind == "scale":
        assert image[0, 10, 10] == pytest.approx(0.5)
    else:
        assert np.isnan(image[:, :4, :4]).all() and np.all(image[:, 4:, 4:] == 0.25)


def test_an_undeclared_fill_is_refused_in_the_bands_a_header_does_not_mark_bad(tmp_path):
    # -9999 in a band the ENVI header's bbl marks bad (passed through as it is, its values not
    # measurements) is no reason to refuse the image; in a good band it is (test_bad_input.py).
    from brdfcorr.io import rasters

    data = np.full((3, 32, 32), 0.25, "float32")
    data[1, :4, :4] = -9999.0
    path = _write(tmp_path / "image.img", data, driver="ENVI")
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(ns="ENVI", bbl="{1, 0, 1}")
    assert np.nanmin(rasters.open_image(path, chunks=16).values) == -9999.0
    with rasterio.open(path, "r+") as dataset:
        dataset.update_tags(ns="ENVI", bbl="{1, 1, 1}")
    with pytest.raises(InputError, match=r"image \S*image\.img: 16 values of a chunk lie below -0\.5"):
        rasters.open_image(path, chunks=16).values


def test_an_image_is_identified_once_and_its_sizes_are_the_path_s(files, tmp_path, monkeypatch):
    """A correction identifies its image once (product kind, layout; issue 42: it was looked up again
    on every call, 4 times with a given chunk size): the chunk and cache sizes of the identified file
    are those of its path, and ``correct_files`` asks for the product kind once."""
    from brdfcorr.io import product, rasters
    from brdfcorr.io.scene import SceneSources
    from brdfcorr.tasks.correct import correct_files
    from brdfcorr.tasks.request import CorrectionRequest, Engine, OutputFiles
    from brdfcorr.testing import example_table

    image = rasters.identify_image(files["image"])
    with rasterio.open(files["image"]) as dataset:
        assert (image.product, image.bands, image.layout.height, image.layout.width) == (
            None, dataset.count, dataset.height, dataset.width)
        assert (image.layout.block_rows, image.layout.block_columns) == dataset.block_shapes[0]
    assert rasters.auto_chunk(image) == rasters.auto_chunk(files["image"])
    assert rasters.gdal_cache_bytes(image, 16) == rasters.gdal_cache_bytes(files["image"], 16)
    calls = []
    original = product.hdf5_product
    monkeypatch.setattr(product, "hdf5_product", lambda path: calls.append(path) or original(path))
    for chunks in (16, None):
        calls.clear()
        correct_files(CorrectionRequest(
            SceneSources(files["image"], files["classes"], files["angles"]), example_table(),
            OutputFiles(tmp_path / f"out{chunks}.tif"), reference={"sza": 35.0},
            engine=Engine(chunks=chunks, scheduler="synchronous")))
        assert calls == [files["image"]]


def test_a_scene_opened_for_a_run_carries_the_sizes_of_its_image(files):
    """``opened_scene`` identifies the image once and carries what follows (issue 42): the chunk
    size and GDAL cache of the path (each worked out from the file again here), the thread count of
    the scene's passes, and, inside the block, GDAL's cache bounded to it."""
    from brdfcorr.io import product
    from brdfcorr.io.scene import SceneSources, opened_scene
    from brdfcorr.io.writer import pass_threads

    sources = SceneSources(files["image"], files["classes"], files["angles"])
    with opened_scene(sources, scheduler="threads") as scene:
        assert rasterio.env.getenv()["GDAL_CACHEMAX"] == scene.cache
        assert scene.image == product.identify_image(files["image"])
        assert scene.chunks == product.auto_chunk(files["image"])
        assert scene.cache == product.gdal_cache_bytes(files["image"], scene.chunks)
        assert scene.threads == pass_threads("threads", None)
        assert scene.reflectance.chunks[-1][0] == min(scene.chunks, scene.reflectance.sizes["x"])
    with opened_scene(sources, chunks=16, scheduler="synchronous") as scene:
        assert scene.chunks == 16 and scene.reflectance.chunks[-1][0] == 16


_SIGNAL_WHILE_A_TEMPORARY_IS_MADE = """
import os, signal, sys
from pathlib import Path
import numpy as np, xarray as xr
from brdfcorr.io.files import atomic_path
from brdfcorr.io.writer import write_rasters
from brdfcorr.testing import georeference

def interrupted(*_):
    raise KeyboardInterrupt
signal.signal(signal.SIGTERM, interrupted)
chmod = os.chmod
def chmod_and_signal(*args, **kwargs):  # the last step of making a temporary file: a SIGTERM lands here
    chmod(*args, **kwargs)
    os.kill(os.getpid(), signal.SIGTERM)
os.chmod = chmod_and_signal
folder = Path(sys.argv[1])
image = georeference(xr.DataArray(np.zeros((1, 16, 16), "float32"), dims=("band", "y", "x")))
for write in (lambda: atomic_path(folder / "table.yaml").__enter__(),
              lambda: write_rasters({folder / "out.tif": image})):
    try:
        write()
    except KeyboardInterrupt:
        print("interrupted")
"""


def test_an_interrupt_while_a_temporary_file_is_made_leaves_no_file(tmp_path):
    # A Ctrl-C or SIGTERM between the making of a temporary file and the recording of its name
    # left a `.NAME.XXXXXXXX.partial` that no cleanup knew (a real SIGINT during `brdfcorr demo`
    # left `.demo.yaml.*.partial`): held back while the file is made, it arrives where the
    # cleanup removes the file. A fresh interpreter: the signal is sent to the process itself.
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-c", _SIGNAL_WHILE_A_TEMPORARY_IS_MADE, str(tmp_path)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["interrupted", "interrupted"]
    assert list(tmp_path.iterdir()) == []
