"""Scaled integer images (issue 14): the GDAL scale/offset is applied on read, given ones replace it,
outputs hold reflectance factors with the scaling in their tags, and raw counts are refused.

Each stored image is made from the float image of the same scene (``counts = round((reflectance -
offset) / scale)``), so the float image's results are the reference, to within the quantization
step of the storage.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import rasterio
import yaml
from click.testing import CliRunner

from brdfcorr.cli import main
from brdfcorr.errors import InputError
from brdfcorr.fit.classes import Sampling
from brdfcorr.io import rasters, scale_check
from brdfcorr.io.angles import open_angles
from brdfcorr.params import ParameterTable
from brdfcorr.tasks.fit import SceneFiles, fit_class_files
from brdfcorr.testing import example_table, synthetic_scene, write_scene

#: name -> (dtype, scale, offset, nodata): reflectance x 10000 in int16, Landsat Collection 2 level 2.
STORAGE = {
    "int16": ("int16", 1e-4, 0.0, -9999),
    "landsat_c2": ("uint16", 2.75e-5, -0.2, 0),
}


@pytest.fixture(scope="module")
def files(tmp_path_factory, store, write_example_scene):
    directory = tmp_path_factory.mktemp("scaled")
    paths = write_example_scene(directory, synthetic_scene(ny=40, nx=48))
    for name, storage in STORAGE.items():
        paths[name] = store(paths["image"], directory / f"{name}.tif", *storage)
        paths[f"{name}_untagged"] = store(paths["image"], directory / f"{name}_untagged.tif", *storage, tag=False)
    return paths


def _invoke(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def _correct(files, image, output, *extra):
    result = _invoke("correct", image, "--angles", files["angles"], "--classes", files["classes"],
                     "--params", files["params"], "-o", output, "--chunk", 16, "--no-progress", *extra)
    assert result.exit_code == 0, result.output
    with rasterio.open(output) as dataset:
        return dataset.read(), {"tags": dataset.tags(), "dtypes": dataset.dtypes, "nodata": dataset.nodata,
                                "scales": dataset.scales, "offsets": dataset.offsets}


def _float_reference(files, directory):
    """The float image corrected, and the correction factor of each pixel."""
    corrected, _ = _correct(files, files["image"], directory / "float.tif")
    with rasterio.open(files["image"]) as dataset:
        return corrected, corrected / dataset.read()


def _one_error_line(result) -> str:
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("brdfcorr: error: "), lines[0]
    return lines[0]


# ---------------------------------------------------------------------------------- open_image
@pytest.mark.parametrize("name", list(STORAGE))
def test_open_image_applies_the_file_scale_and_offset(files, name, nodata_pixels):
    _, scale, offset, _ = STORAGE[name]
    image = rasters.open_image(files[name], chunks=16)
    with rasterio.open(files["image"]) as dataset:
        truth = dataset.read()
    values = image.values
    assert image.dtype == np.float32
    assert np.isnan(values[nodata_pixels]).all()
    valid = np.isfinite(values)
    assert valid.sum() == values.size - values[nodata_pixels].size
    np.testing.assert_allclose(values[valid], truth[valid], rtol=0, atol=scale / 2 + 1e-7)  # + float32 rounding
    assert image.attrs["brdf_input_scale"] == scale and image.attrs["brdf_input_offset"] == offset
    assert "scale_factor" not in image.attrs and "add_offset" not in image.attrs
    np.testing.assert_allclose(image["wavelength"], [480, 560, 660, 830])


def test_open_image_per_band_scales_and_given_values(files, tmp_path, store):
    scales, offsets = [1e-4, 2e-4, 1e-4, 5e-5], [0.0, -0.1, 0.0, 0.05]
    path = store(files["image"], tmp_path / "bands.tif", "int16", None, None, -9999, scales=scales, offsets=offsets)
    with rasterio.open(files["image"]) as dataset:
        truth = dataset.read()
    image = rasters.open_image(path)  # rioxarray applies each band's own scale and offset
    valid = np.isfinite(image.values)
    np.testing.assert_allclose(image.values[valid], truth[valid], rtol=0, atol=max(scales) / 2 + 1e-7)
    assert image.attrs["brdf_input_scale"] == tuple(scales)
    assert image.attrs["brdf_input_offset"] == tuple(offsets)
    # A given value replaces the file's for every band; the one not given stays the file's.
    given = rasters.open_image(path, scale=3e-4)
    with rasterio.open(path) as dataset:
        counts = dataset.read(masked=True).astype(float).filled(np.nan)
    expected = counts * 3e-4 + np.asarray(offsets)[:, None, None]
    np.testing.assert_allclose(given.values, expected, rtol=1e-6, atol=1e-7, equal_nan=True)  # float32
    assert given.dtype == np.float32
    assert given.attrs["brdf_input_scale"] == 3e-4 and given.attrs["brdf_input_offset"] == tuple(offsets)
    with pytest.raises(InputError, match=r"scale -1\.0 must be > 0"):
        rasters.open_image(path, scale=-1.0)


@pytest.mark.parametrize(("dtype", "expected"), [("int32", np.float32), ("float64", np.float64)])
def test_open_image_gives_float32_unless_the_file_is_float64(files, tmp_path, dtype, expected, store):
    path = store(files["image"], tmp_path / f"{dtype}.tif", dtype, 1e-4, 0.0, -9999)
    assert rasters.open_image(path).dtype == expected


# ------------------------------------------------------------------------------------- correct
@pytest.mark.parametrize("name", list(STORAGE))
def test_correct_scaled_image_matches_the_float_image(files, tmp_path, name, nodata_pixels):
    _, scale, offset, _ = STORAGE[name]
    reference, factor = _float_reference(files, tmp_path)
    corrected, written = _correct(files, files[name], tmp_path / "out.tif")
    tags = written["tags"]
    assert float(tags["brdf_input_scale"]) == scale and float(tags["brdf_input_offset"]) == offset
    # Reflectance factors, not counts: float32, no GDAL scale/offset, NaN nodata.
    assert written["dtypes"] == ("float32",) * 4 and np.isnan(written["nodata"])
    assert written["scales"] == (1.0,) * 4 and written["offsets"] == (0.0,) * 4
    assert np.isnan(corrected[nodata_pixels]).all()
    valid = np.ones(corrected.shape, bool)
    valid[nodata_pixels] = False
    assert np.isfinite(corrected[valid]).all()
    # Within the correction factor times half the quantization step (plus float32 rounding).
    tolerance = factor * scale / 2 * 1.001 + 1e-6
    assert (np.abs(corrected - reference)[valid] <= tolerance[valid]).all()


@pytest.mark.parametrize("name", list(STORAGE))
def test_given_scale_and_offset_on_an_untagged_image_give_the_same(files, tmp_path, name):
    _, scale, offset, _ = STORAGE[name]
    tagged, _ = _correct(files, files[name], tmp_path / "tagged.tif")
    given, written = _correct(files, files[f"{name}_untagged"], tmp_path / "given.tif",
                              "--scale", scale, "--offset", offset)
    np.testing.assert_allclose(given, tagged, rtol=1e-6, equal_nan=True)
    tags = written["tags"]
    assert float(tags["brdf_input_scale"]) == scale and float(tags["brdf_input_offset"]) == offset


def test_given_scale_wins_over_the_tagged_one(files, tmp_path):
    tagged, _ = _correct(files, files["int16"], tmp_path / "tagged.tif")
    doubled, written = _correct(files, files["int16"], tmp_path / "doubled.tif", "--scale", 2e-4)
    # The correction is a factor: twice the input reflectance, twice the output (limits not hit).
    np.testing.assert_allclose(doubled, 2 * tagged, rtol=1e-6, equal_nan=True)
    assert written["tags"]["brdf_input_scale"] == "0.0002"


# ---------------------------------------------------------------------------------- fit-classes
@pytest.fixture(scope="module")
def fit_files(tmp_path_factory, store):
    """One Torrance-Sparrow class over a wider scene: a fit the data constrain."""
    directory = tmp_path_factory.mktemp("scaled_fit")
    table = ParameterTable(classes=[example_table()[1]])
    paths = write_scene(directory, synthetic_scene(ny=64, nx=96, table=table))
    for name, storage in STORAGE.items():
        paths[name] = store(paths["image"], directory / f"{name}.tif", *storage)
    paths["int16_untagged"] = store(paths["image"], directory / "int16_untagged.tif", *STORAGE["int16"], tag=False)
    with rasterio.open(paths["image"]) as dataset:
        paths["median"] = float(np.median(dataset.read()))
    return paths


def _fit(files, image, output, *extra):
    return _invoke("fit-classes", image, "--angles", files["angles"], "--classes", files["classes"],
                   "-o", output, *extra)


@pytest.mark.parametrize("name", list(STORAGE))
def test_fit_classes_on_the_scaled_image_matches_the_float_image(fit_files, tmp_path, name):
    _, scale, _, _ = STORAGE[name]
    reports = {}
    for image, output in ((fit_files["image"], "float"), (fit_files[name], "scaled")):
        result = _fit(fit_files, image, tmp_path / f"{output}.yaml", "--report", tmp_path / f"{output}.json")
        assert result.exit_code == 0, result.output
        reports[output] = json.loads((tmp_path / f"{output}.json").read_text())["classes"][0]
    reference, scaled = (ParameterTable.load(tmp_path / f"{n}.yaml")[1] for n in ("float", "scaled"))
    assert scaled.model == reference.model and reports["scaled"]["status"] == reports["float"]["status"] == "fitted"
    assert 0.001 < reference.params["t0"] < 0.1  # reflectance factors [sr^-1], not counts
    # The linear parameter moves by about the relative quantization step at the median reflectance;
    # every parameter by a small fraction of its own 1-sigma fit error.
    np.testing.assert_allclose(scaled.params["t0"], reference.params["t0"], rtol=scale / fit_files["median"])
    for parameter, value in reference.params.items():
        error = np.asarray(reports["float"]["errors"][parameter])
        assert np.all(np.abs(np.asarray(scaled.params[parameter]) - value) <= 0.05 * error), parameter


def test_fit_class_files_reflectance_scale_is_the_scale_on_read(fit_files):
    def fit(scale=None, reflectance_scale=1.0):
        scene = SceneFiles(fit_files["int16_untagged"], fit_files["classes"], fit_files["angles"], scale=scale)
        sampling = Sampling(reflectance_scale=reflectance_scale)
        return fit_class_files([scene], "torrance_sparrow", sampling=sampling).table[1].params

    assert fit(reflectance_scale=1e-4) == fit(scale=1e-4)
    with pytest.raises(InputError, match="raw counts"):
        fit()
    with pytest.raises(InputError, match="give the scale once"):
        fit(scale=2e-4, reflectance_scale=1e-4)


# -------------------------------------------------------------------------------- raw-count guard
@pytest.mark.parametrize("command", ["correct", "fit-classes"])
def test_raw_counts_without_a_scale_are_one_error(files, tmp_path, command):
    output = tmp_path / ("out.tif" if command == "correct" else "params.yaml")
    if command == "correct":
        result = _invoke("correct", files["int16_untagged"], "--angles", files["angles"], "--classes",
                         files["classes"], "--params", files["params"], "-o", output, "--no-progress")
    else:
        result = _fit(files, files["int16_untagged"], output)
    assert result.exit_code == 2, result.output
    line = _one_error_line(result)
    assert "int16_untagged.tif: the values do not look like reflectance factors" in line
    assert "raw counts?" in line and "--scale" in line
    assert not output.exists()


@pytest.mark.parametrize("kind", ["reflectance x 10000 as float", "divisor scale tag"])
def test_scaled_floats_and_divisor_tags_are_one_error_naming_scale(files, tmp_path, kind, store, nodata_pixels):
    # Reflectance x 10000 kept as float32 (HyTools, NEON, many ENVI cubes), and int16 counts whose
    # GDAL scale tag is the divisor 10000 (the MODIS HDF convention) instead of 0.0001: both would
    # be "corrected" into numbers 10^4 or 10^8 too large; each is refused before any output.
    if kind == "divisor scale tag":
        image = store(files["image"], tmp_path / "divisor.tif", "int16", 1e-4, 0.0, -9999, tag=False)
        with rasterio.open(image, "r+") as dataset:
            dataset.scales = [1e4] * dataset.count
    else:
        image = store(files["image"], tmp_path / "float_x10000.tif", "float32", 1e-4, 0.0, -9999, tag=False)
    for command in ("correct", "fit-classes"):
        output = tmp_path / ("out.tif" if command == "correct" else "params.yaml")
        result = (_invoke("correct", image, "--angles", files["angles"], "--classes", files["classes"],
                          "--params", files["params"], "-o", output, "--no-progress")
                  if command == "correct" else _fit(files, image, output))
        assert result.exit_code == 2, result.output
        line = _one_error_line(result)
        assert f"{image.name}: the values do not look like reflectance factors" in line
        assert "--scale 0.0001" in line and not output.exists()
        assert ("looks like a divisor" in line) == (kind == "divisor scale tag")
    # With the scale given, the same image corrects like the float reflectance image.
    reference, _ = _float_reference(files, tmp_path)
    corrected, _ = _correct(files, image, tmp_path / "given.tif", "--scale", 1e-4)
    valid = np.isfinite(corrected)
    assert np.isnan(corrected[nodata_pixels]).all() and valid.sum() == corrected.size - corrected[nodata_pixels].size
    np.testing.assert_allclose(corrected[valid], reference[valid], rtol=1e-3, atol=2e-4)


def test_a_given_scale_is_trusted(files, tmp_path):
    # --scale 1: the counts as they are, on the user's word (no guard).
    counts, written = _correct(files, files["int16_untagged"], tmp_path / "counts.tif", "--scale", 1)
    assert written["tags"]["brdf_input_scale"] == "1.0"
    assert np.nanpercentile(counts, 99) > 1000


# ------------------------------------------------------------------------------------ chain keys
def test_chain_inputs_scale_and_offset(files, tmp_path):
    _, scale, offset, _ = STORAGE["landsat_c2"]
    reference, _ = _correct(files, files["landsat_c2"], tmp_path / "tagged.tif")
    document = {
        "inputs": {"images": [str(files["landsat_c2_untagged"])],
                   "angles": {"kind": "geotiff", "path": str(files["angles"])}, "classes": str(files["classes"]),
                   "scale": scale, "offset": offset},
        "parameters": {"table": str(files["params"])},
        "steps": {"correct": {"qa": False}, "quicklook": None},
        "outputs": {"directory": str(tmp_path / "out"), "naming": "{stem}_brdf.tif"},
        "engine": {"scheduler": "synchronous", "workers": 1, "chunk": 16},
    }
    chain = tmp_path / "chain.yaml"
    chain.write_text(yaml.safe_dump(document))
    result = _invoke("run", chain, "--no-progress")
    assert result.exit_code == 0, result.output
    with rasterio.open(tmp_path / "out" / "landsat_c2_untagged_brdf.tif") as dataset:
        np.testing.assert_allclose(dataset.read(), reference, rtol=1e-6, equal_nan=True)
        assert dataset.tags()["brdf_input_offset"] == "-0.2"


def _reflectance_cube(values, chunks):
    """A lazily chunked (band, y, x) image as :func:`rasters.open_image` gives one."""
    import dask.array
    import xarray as xr

    return xr.DataArray(dask.array.from_array(values, chunks=(values.shape[0], chunks, chunks)),
                        dims=("band", "y", "x"))


def test_scale_check_reads_only_the_central_chunk_when_it_holds_enough(monkeypatch):
    # Each chunk read decompresses its input tiles (a sixth of a 1 GiB cube's correction time for
    # nine chunks, issue 28): one chunk of 4 x 80 x 80 valid values is enough to judge by.
    read = []
    sample = scale_check._valid_sample
    monkeypatch.setattr(scale_check, "_valid_sample", lambda block, *a, **k: read.append(block.shape) or sample(block))
    values = np.random.default_rng(0).uniform(0.0, 0.5, (4, 400, 400)).astype("float32")
    assert scale_check.check_reflectance_scale(_reflectance_cube(values, 80), scheduler="synchronous") <= 0.5
    assert read == [(4, 80, 80)]


def test_scale_check_looks_beyond_an_empty_centre():
    # Reflectance x 10 000 stored as floats, the centre of the scene without data (a flight line's
    # footprint, a partly covered tile): the spread chunks still find the values and refuse them.
    values = np.random.default_rng(0).uniform(0.0, 5000.0, (4, 400, 400)).astype("float32")
    values[:, 160:240, 160:240] = np.nan
    with pytest.raises(InputError, match=r"reflectance \* scale \+ offset before the call \(or scale=/offset="):
        scale_check.check_reflectance_scale(_reflectance_cube(values, 80), scheduler="synchronous")


def test_an_angle_file_of_scaled_integers_is_read_in_degrees(files, tmp_path, store, nodata_pixels):
    # Hundredths of a degree in uint16 with a GDAL scale of 0.01 (as Landsat and Sentinel-2 angle
    # bands are stored): read with the file's scale, as the image is; taken as they are, every sun
    # zenith (e.g. 3000) would be outside [0, 90) and the pixel left uncorrected.
    angles = store(files["angles"], tmp_path / "angles_uint16.tif", "uint16", 0.01, 0.0, 65535)
    opened = open_angles(angles)
    with rasterio.open(files["angles"]) as dataset:
        truth = dataset.read()
    for index, name in enumerate(("sza", "saa", "vza", "vaa")):
        values = opened[name].values
        assert np.isnan(values[nodata_pixels[1:]]).all()
        valid = np.isfinite(values)
        np.testing.assert_allclose(values[valid], truth[index][valid], rtol=0, atol=0.005 + 1e-4)
    reference, _ = _correct(files, files["image"], tmp_path / "float_angles.tif")
    corrected, _ = _correct(files, files["image"], tmp_path / "scaled_angles.tif", "--angles", angles)  # the last
    both = np.isfinite(corrected) & np.isfinite(reference)
    assert both.mean() > 0.95  # only the nodata pixels of the angle file are left out
    np.testing.assert_allclose(corrected[both], reference[both], rtol=2e-3)  # angles to 0.005 deg


def _envi_counts(source, target, factor: str):
    """``source`` (float reflectance) as an ENVI int16 cube of reflectance x 10 000, its header
    saying ``reflectance scale factor = {factor}`` (and GDAL tagging no scale of its own)."""
    with rasterio.open(source) as dataset:
        profile, values, descriptions = dataset.profile, dataset.read(), dataset.descriptions
    profile.update(driver="ENVI", dtype="int16", nodata=-9999)
    for key in ("tiled", "blockxsize", "blockysize", "compress", "interleave"):
        profile.pop(key, None)
    counts = np.where(np.isfinite(values), np.round(values * 10000), -9999).astype("int16")
    with rasterio.open(target, "w", **profile) as dataset:
        dataset.write(counts)
        dataset.descriptions = descriptions
        dataset.update_tags(ns="ENVI", reflectance_scale_factor=factor)
    return target


def test_an_envi_cube_is_scaled_by_its_headers_reflectance_scale_factor(files, tmp_path):
    # ENVI's definition: the value that, divided into the data, gives reflectance 0-1 (HyTools and
    # many ENVI cubes store reflectance x 10 000 with 10000 there). It was ignored: the cube was
    # refused as raw counts, a --scale needed although the header said it.
    cube = _envi_counts(files["image"], tmp_path / "cube.img", "10000")
    image = rasters.open_image(cube, chunks=16)
    with rasterio.open(files["image"]) as dataset:
        truth = dataset.read()
    assert image.attrs["brdf_input_scale"] == 1e-4
    np.testing.assert_allclose(image.values, truth, rtol=0, atol=0.5e-4 + 1e-7)
    reference, _ = _correct(files, files["image"], tmp_path / "float.tif")
    corrected, metadata = _correct(files, cube, tmp_path / "cube.tif")
    np.testing.assert_allclose(corrected, reference, rtol=0, atol=2e-4)  # the counts' quantization, corrected
    assert metadata["tags"]["brdf_input_scale"] == "0.0001"
    _envi_counts(files["image"], tmp_path / "bad.img", "ten thousand")
    result = _invoke("correct", tmp_path / "bad.img", "--angles", files["angles"], "--classes", files["classes"],
                     "--params", files["params"], "-o", tmp_path / "bad.tif", "--no-progress")
    assert result.exit_code == 2
    assert "its ENVI header's reflectance scale factor 'ten thousand' is no positive number" in _one_error_line(result)
